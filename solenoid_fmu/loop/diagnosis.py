"""Residual diagnosis: trace the difference between measured and simulated signals to an effect.

Each candidate effect the real-time model lacks has a *signature*: a small set of features,
computed from the recording's inputs and the simulated flux, that the residual must be a
linear combination of if that effect caused it.

========== ====================================================================================
effect     features (the residual is a linear combination of these)
========== ====================================================================================
hysteresis stop operators of Psi at four thresholds, each also times |Psi| and Psi^2 (the loop
           width changes along the curve): rate-independent, depend on the direction and
           history of dPsi/dt, loops that widen with amplitude
eddy       dPsi/dt low-pass filtered with time constants 0.1, 1 and 10 ms (a ladder of eddy paths;
           a single G_eddy is dPsi/dt itself, which the model already has): grows with rate
heating    current times the temperature rise of a first-order thermal model driven by i^2 R,
           for thermal time constants 30 s to 20 min: grows with dissipated energy over time
friction   sign of the armature's last motion (force only): flips with the direction of
           motion and holds while the armature stands
sensor     a constant and the simulated signal (offset and gain) of current, voltage, force
material   a cubic polynomial in the normalized (Psi, x): a single-valued function of Psi and x
           alone, as a wrong B(H) curve leaves it
========== ====================================================================================

A wrong B(H) curve (``material``) is the baseline: every other effect is scored by what its
features explain beyond the material polynomial, so a flexible signature cannot claim the smooth
part of a residual. (A current-sensor gain error is, like a uniformly scaled B(H), a smooth
function of Psi: it is reported as ``material``; a sensor offset is not.)

Evidence that cannot be gamed by adding parameters: the features are fitted on one half of the
data and scored on the other half (two-fold cross-validation over recordings, dealt out by the
size of their excitations, or over 20 alternating blocks in time when there is only one
recording: :func:`solenoid_fmu.loop.split.cv_folds`). The score of an effect is the share of the
held-out residual variance its fit explains, pooled over all residual signals (each signal
normalized by its measured range). The verdict is the best effect if its score clears
``threshold`` (default 0.25), else ``"unexplained"``: noise cannot be predicted on held-out
data, so a model that lacks nothing scores near zero everywhere.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..measure import armature_moves
from .residuals import ResidualCase
from .signals import detrend, lowpass
from .split import cv_folds

EFFECTS = ("hysteresis", "eddy", "heating", "friction", "sensor", "material")
SIGNALS = ("current_A", "voltage_V", "force_N", "psi_Wb")
DEFAULT_THRESHOLD = 0.25
#: Residuals smaller than this RMS share of the measured range are "nothing to explain".
DEFAULT_MIN_NRMS = 0.003


@dataclass
class Candidate:
    """One effect's evidence.

    ``score``: held-out share of residual energy it explains beyond its partner (the ranking
    key); ``explained``: held-out share its features explain on their own (0..1);
    ``per_signal``: the score per residual signal.
    """

    effect: str
    score: float
    explained: float
    per_signal: dict = field(default_factory=dict)
    n_features: int = 0

    def as_dict(self) -> dict:
        return {"effect": self.effect, "score": self.score, "explained": self.explained,
                "per_signal": self.per_signal, "n_features": self.n_features}


@dataclass
class Diagnosis:
    """Ranked candidates and the verdict (an effect name or ``"unexplained"``)."""

    ranking: list
    verdict: str
    threshold: float
    residual_nrms: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return {"ranking": [c.as_dict() for c in self.ranking], "verdict": self.verdict,
                "threshold": self.threshold, "residual_nrms": self.residual_nrms}


# -- signatures ----------------------------------------------------------------------------------
def _stop(b: np.ndarray, r: float) -> np.ndarray:
    """Stop operator b - play_r(b), starting relaxed at b[0] (rate independent)."""
    out = np.empty_like(b)
    if b.dtype != np.float64 or b.ndim != 1 or not r >= 0.0:
        y = b[0]
        for k, v in enumerate(b):
            y = min(max(y, v - r), v + r)
            out[k] = v - y
        return out
    # the same over Python floats (float64's IEEE doubles, no numpy scalar per sample); for r >= 0 the
    # clamp min(max(y, v - r), v + r) in two comparisons, as the model's play operator writes it
    y = b[0].item()
    res = []
    for v in b.tolist():
        lo = v - r
        hi = v + r
        if y < lo:
            y = lo
        elif y > hi:
            y = hi
        res.append(v - y)
    out[:] = res
    return out


def _ddt(y: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.gradient(y, t) if len(t) > 2 else np.zeros_like(y)


def features(effect: str, case: ResidualCase, signal: str, scales: dict) -> np.ndarray | None:
    """Feature matrix (n, p) of ``effect`` for ``signal`` of ``case``, or None if not applicable.

    ``scales`` holds global normalizations (``psi`` [Wb], ``x`` [m], ``x_span`` [m]) so that
    features are comparable across recordings. For a signal in ``case.detrended`` the features
    are projected orthogonal to ``a + b t`` like its residual.
    """
    X = _features(effect, case, signal, scales)
    if X is not None and signal in case.detrended:
        X = detrend(X, case.time_s)
    return X


def _features(effect: str, case: ResidualCase, signal: str, scales: dict) -> np.ndarray | None:
    t = case.time_s
    psi = case.psi_Wb / scales["psi"]
    n = len(t)
    if effect == "hysteresis":
        # stops at four thresholds, their width shaped by |Psi| (loops narrow in saturation)
        stops = [_stop(psi, r) for r in (0.01, 0.03, 0.08, 0.2)]
        return np.column_stack([s * np.abs(psi) ** k for s in stops for k in (0, 1, 2)])
    if effect == "eddy":
        dpsi = _ddt(case.psi_Wb, t) / scales["dpsi"]
        return np.column_stack([lowpass(dpsi, t, tau) for tau in (1e-4, 1e-3, 1e-2)])
    if effect == "heating":
        if signal not in ("voltage_V", "current_A", "psi_Wb"):
            return None
        # Within one recording (seconds to minutes) the coil heats adiabatically: the temperature
        # rise is int i^2 R dt / C_th. One column, so that its coefficient (alpha / C_th) is the
        # same in every recording: several thermal time constants would be collinear over a short
        # recording and their fitted mix would not carry over to the next (held-out) one.
        p = case.current_A**2 * case.R_ohm
        rise = np.concatenate([[0.0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(t))])
        ohmic = case.current_A * rise  # i * dR: the voltage (or, negated, current) error
        if signal == "psi_Wb":  # eq. 4 with the header R integrates the ohmic error
            ohmic = np.concatenate([[0.0], np.cumsum(0.5 * (ohmic[1:] + ohmic[:-1]) * np.diff(t))])
        return ohmic[:, None]
    if effect == "friction":
        if signal != "force_N":
            return None
        # the armature stands (or its position sensor only shows noise): no sliding friction
        if np.ptp(case.position_m) < 0.01 * scales["x_span"] or not armature_moves(case.position_m):
            return None
        v = _ddt(case.position_m, t)
        vs = np.nanmax(np.abs(v)) if n else 0.0
        # the direction of the last motion: friction holds its sign when the armature stops
        moving = np.abs(v) > 1e-3 * vs
        idx = np.where(moving, np.arange(n), -1)
        last = np.maximum.accumulate(idx)
        held = np.where(last >= 0, np.sign(v[np.maximum(last, 0)]), 0.0)
        return held[:, None]
    if effect == "sensor":
        meas = case.measured.get(signal)
        if meas is None or signal == "psi_Wb":  # Psi is derived (eq. 4), its offsets are removed there
            return None
        # gain on the *simulated* signal (measured minus residual): a gain on the measured one would
        # contain the residual itself, and together with the material polynomial span any residual
        sim = meas - case.residuals[signal]
        return np.column_stack([np.ones(n), sim / scales["range"].get(signal, 1.0)])
    if effect == "material":
        x = (case.position_m - scales["x"]) / max(scales["x_span"], 1e-30)
        cols = [psi, psi**2, psi**3, psi * x, psi**2 * x, psi * x**2]
        return np.column_stack(cols)
    raise ValueError(f"unknown effect {effect!r}; use one of {EFFECTS}")


class _Memo:
    """One diagnosis's scales, features and cross-validated fits, each computed once: :func:`diagnose` scores
    every effect on the same cases against the same partner, and :func:`score_effect` asks for the effect's
    own fit twice (the same inputs, so the same numbers)."""

    def __init__(self, cases: list[ResidualCase]):
        self.scales = _scales(cases)
        self.features: dict = {}
        self.cv: dict = {}

    def feature(self, effect: str, k: int, case: ResidualCase, signal: str) -> np.ndarray | None:
        """:func:`features` of the ``k``-th case (the arrays are read, never written, by the callers)."""
        key = (effect, k, signal)
        if key not in self.features:
            self.features[key] = features(effect, case, signal, self.scales)
        return self.features[key]


def _scales(cases: list[ResidualCase]) -> dict:
    psi = max(np.max(np.abs(c.psi_Wb)) for c in cases) or 1.0
    dpsi = max(np.max(np.abs(_ddt(c.psi_Wb, c.time_s))) for c in cases) or 1.0
    xs = np.concatenate([c.position_m for c in cases])
    ranges = {}
    for signal in SIGNALS:
        vals = [np.ptp(c.measured[signal]) for c in cases if signal in c.measured]
        if vals:
            ranges[signal] = max(max(vals), 1e-30)
    return {"psi": psi, "dpsi": dpsi, "x": float(np.mean(xs)), "x_span": float(np.ptp(xs)) or 1.0,
            "range": ranges}


def _cv_sse(effects: tuple, cases: list[ResidualCase], signal: str, scales: dict,
            balanced: bool = False, memo: _Memo | None = None) -> tuple[float, float, int]:
    """Held-out SSE and SS of the normalized residual of ``signal`` fitted by the union of the
    features of ``effects`` (two-fold cross-validation); (0, 0, 0) when nothing applies. ``memo``: the
    diagnosis's (:class:`_Memo`, made with these cases and ``scales``)."""
    if memo is not None:
        key = (tuple(effects), signal, balanced)
        if key not in memo.cv:
            memo.cv[key] = _cv_sse_of(effects, cases, signal, scales, balanced,
                                      lambda e, k, c: memo.feature(e, k, c, signal))
        return memo.cv[key]
    return _cv_sse_of(effects, cases, signal, scales, balanced, lambda e, k, c: features(e, c, signal, scales))


def _cv_sse_of(effects: tuple, cases: list[ResidualCase], signal: str, scales: dict, balanced: bool,
               feature) -> tuple[float, float, int]:
    """:func:`_cv_sse` with the features of ``signal`` by ``feature(effect, k, case)``."""
    feats = [[feature(e, k, c) if signal in c.residuals else None for e in effects] for k, c in enumerate(cases)]
    # an effect that applies to some recordings only gets zero columns in the others
    widths = [next((f[j].shape[1] for f in feats if f[j] is not None), 0) for j in range(len(effects))]
    data = []
    for c, f in zip(cases, feats, strict=True):
        res = c.residuals.get(signal)
        if res is None or all(X is None for X in f):
            data.append(None)
            continue
        norm = scales["range"].get(signal, max(np.ptp(res), 1e-30))
        cols = [X if X is not None else np.zeros((len(res), w)) for X, w in zip(f, widths, strict=True) if w]
        data.append((np.column_stack(cols), res / norm))
    # balanced: no recording counts for more than the median one. A recording whose residual is far
    # larger than the others' (one strongly heated run, say) is weighted down to the median RMS, so
    # that the evidence of the other recordings is not drowned (weighted least squares, weights <= 1)
    rms = [float(np.sqrt(np.mean(d[1] ** 2))) if d is not None else 0.0 for d in data]
    if balanced and any(d is not None for d in data):
        q = float(np.median([r for r, d in zip(rms, data, strict=True) if d is not None]))
        data = [None if d is None else (d[0] * (q / max(r, q, 1e-300)), d[1] * (q / max(r, q, 1e-300)))
                for d, r in zip(data, rms, strict=True)]
    sse, ss, p = 0.0, 0.0, 0
    for train, test in cv_folds(cases):
        Xt = [data[k][0][m] for k, m in train if data[k] is not None]
        yt = [data[k][1][m] for k, m in train if data[k] is not None]
        Xv = [data[k][0][m] for k, m in test if data[k] is not None]
        yv = [data[k][1][m] for k, m in test if data[k] is not None]
        if not Xt or not Xv:
            continue
        Xt, yt, Xv, yv = map(np.concatenate, (Xt, yt, Xv, yv))
        coef, *_ = np.linalg.lstsq(Xt, yt, rcond=None)
        ssv = float(np.sum(yv**2))
        # a fit that predicts the held-out half worse than zero explains nothing (no extrapolation credit)
        sse += min(float(np.sum((yv - Xv @ coef) ** 2)), ssv)
        ss += ssv
        p = Xt.shape[1]
    return sse, ss, p


def score_effect(effect: str, cases: list[ResidualCase], signals=SIGNALS, partner: str = "material",
                 balanced: bool = False, memo: _Memo | None = None) -> Candidate:
    """Held-out share of residual energy that ``effect`` explains beyond ``partner``.

    Per signal: ``(SSE(partner) - min(SSE(partner + effect), SSE(effect))) / SS``, all held out.

    Every effect other than ``material`` is scored by what it adds to the material polynomial (a
    smooth function of Psi and x that a corrected B(H) would remove); ``material`` itself is
    scored by what it adds to the best other effect (see :func:`diagnose`). So neither a flexible
    signature nor the smooth baseline can claim what the other explains as well.

    ``memo``: the features and fits already computed on these ``cases`` (:func:`diagnose`'s).
    """
    memo = _Memo(cases) if memo is None else memo
    scales = memo.scales
    sse_total, ss_total = 0.0, 0.0
    per_signal = {}
    n_feat = 0
    for signal in signals:
        probe = [memo.feature(effect, k, c, signal) for k, c in enumerate(cases) if signal in c.residuals]
        if all(X is None for X in probe):
            continue
        union = (effect,) if partner in (None, effect) else (partner, effect)
        sse, ss, p = _cv_sse(union, cases, signal, scales, balanced, memo)
        if ss <= 0:
            continue
        if partner in (None, effect):
            base = ss
        else:
            base, _, _ = _cv_sse((partner,), cases, signal, scales, balanced, memo)
            if base == 0.0:  # the partner does not apply to this signal
                base = ss
            # the partner's columns can also spoil the held-out prediction (a smooth polynomial fitted
            # on some recordings extrapolates badly to others): then the effect alone is the better
            # model, and what it explains beyond the partner is measured against that
            # (on the same samples: where the effect does not apply, it leaves the residual as it is)
            sse_alone, ss_alone, _ = _cv_sse((effect,), cases, signal, scales, balanced, memo)
            sse = min(sse, sse_alone + (ss - ss_alone))
        per_signal[signal] = (base - sse) / ss
        sse_total += sse - base
        ss_total += ss
        n_feat = max(n_feat, p)
    score = -sse_total / ss_total if ss_total > 0 else 0.0
    alone = 0.0
    if partner not in (None, effect):
        sse_a = ss_a = 0.0
        for signal in per_signal:
            e, q, _ = _cv_sse((effect,), cases, signal, scales, balanced, memo)
            sse_a += e
            ss_a += q
        alone = 1.0 - sse_a / ss_a if ss_a > 0 else 0.0
    else:
        alone = score
    return Candidate(effect, score=score, explained=min(max(alone, 0.0), 1.0), per_signal=per_signal,
                     n_features=n_feat)


def residual_nrms(cases: list[ResidualCase]) -> dict:
    """RMS residual per signal, relative to the largest measured range of that signal."""
    scales = _scales(cases)
    out = {}
    for signal in SIGNALS:
        res = [c.residuals[signal] for c in cases if signal in c.residuals]
        if res:
            r = np.concatenate(res)
            out[signal] = float(np.sqrt(np.mean(r**2)) / scales["range"].get(signal, max(np.ptp(r), 1e-30)))
    return out


def diagnose(cases: list[ResidualCase], effects=EFFECTS, threshold: float = DEFAULT_THRESHOLD,
             signals=SIGNALS, min_nrms: float = DEFAULT_MIN_NRMS, balanced: bool = False) -> Diagnosis:
    """Rank the candidate effects by held-out explained residual variance; name the verdict.

    Parameters
    ----------
    cases : list of ResidualCase
        One per recording (at least one).
    effects : sequence of str
        Candidates to test (default: all of :data:`EFFECTS`).
    threshold : float
        Minimum held-out explained share for a verdict; below it the answer is ``"unexplained"``.
    min_nrms : float
        When every signal's residual RMS is below this share of its measured range, the model
        already matches and the answer is ``"unexplained"`` whatever the scores.
    balanced : bool
        Weight the recordings so that none counts for more than the median one (by residual
        RMS): the scores then measure how broadly an effect explains the campaign rather than
        how much residual energy. ``improve`` asks for it when no effect clears its threshold
        unbalanced (one recording's large residual of one effect can drown another effect).
    """
    if not cases:
        raise ValueError("diagnose needs at least one recording")
    memo = _Memo(cases)  # each feature and fit once for all the effects scored
    others = [score_effect(e, cases, signals, balanced=balanced, memo=memo) for e in effects if e != "material"]
    ranking = others
    if "material" in effects:
        best = max(others, key=lambda c: c.score).effect if others else None
        ranking = others + [score_effect("material", cases, signals, partner=best, balanced=balanced, memo=memo)]
    ranking = sorted(ranking, key=lambda c: -c.score)
    nrms = residual_nrms(cases)
    significant = any(v >= min_nrms for v in nrms.values())
    verdict = ranking[0].effect if ranking and significant and ranking[0].score >= threshold else "unexplained"
    return Diagnosis(ranking, verdict, threshold, nrms)

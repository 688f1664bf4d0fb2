"""The closed loop on campaigns from rigs other than ours (issue 12): success rate and time per campaign.

Usage::

    python benchmarks/bench_anyrig.py [N_LOOP] [N_PIPELINE]

Part 1 (``N_LOOP`` campaigns, default 24): randomized-protocol campaigns
(:func:`solenoid_fmu.rig.protocols.random_campaign`, seeds 1000.., up to 6000 samples per recording)
on the synthetic maps of the tests, cycling through one effect each, two pairs, none and a force
sensor fault; :func:`solenoid_fmu.loop.improvement.improve_tables` on the true maps without effects. A
campaign is a success when exactly the true effects are added (nothing for none / sensor fault).
Prints the success rate, the failures by seed, and the loop time per campaign.

Part 2 (``N_PIPELINE`` campaigns, default 2): the whole ``solenoid-fmu pipeline`` (quick FEM preset,
2 workers: identify B(H), maps, eddy, FMUs, improve, report) on randomized campaigns of the true PS45
maps of the demo campaign; prints the effects added and the time per stage.
Baseline in the same run: our own rig's small campaign (tests/conftest.small_campaign) through the
same loop, for the time ratio.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the synthetic maps and our rig's small campaign

SETS = ("hysteresis", "eddy-ladder", "heating", "friction", "hysteresis,friction", "heating,eddy-ladder", "",
        "sensor")
MODEL_NAME = {"hysteresis": "hysteresis", "eddy-ladder": "eddy", "heating": "heating", "friction": "friction"}


def _loop(tables, folder) -> tuple[list, float]:
    from solenoid_fmu.loop import improve_tables
    from solenoid_fmu.measure import read_recording

    recs = [read_recording(p) for p in sorted((folder / "recordings").glob("*.csv"))]
    t0 = time.perf_counter()
    res = improve_tables(tables, recs)
    return sorted(s.effect for s in res.steps if s.accepted and not s.refit), time.perf_counter() - t0


def main(n_loop: int = 24, n_pipeline: int = 2) -> dict:
    import mapsfixture
    from conftest import small_campaign

    from solenoid_fmu.realtime.model import load_tables
    from solenoid_fmu.rig import Effects, random_campaign, run_campaign

    out: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        tables = load_tables(mapsfixture.write_maps(tmp / "maps"))
        run_campaign(tables, tmp / "ours", Effects.from_names("hysteresis,noise"), small_campaign(), seed=1)
        _, t_ours = _loop(tables, tmp / "ours")
        print(f"baseline: our rig's small campaign (hysteresis), loop {t_ours:.1f} s")
        ok, fails, t_gen, t_loop = 0, [], [], []
        for k in range(n_loop):
            seed, fx = 1000 + k, SETS[k % len(SETS)]
            t0 = time.perf_counter()
            random_campaign(tables, tmp / f"c{k}", "" if fx == "sensor" else fx, seed=seed, max_samples=6000,
                            sensor_fault=fx == "sensor")
            t_gen.append(time.perf_counter() - t0)
            try:
                added, dt = _loop(tables, tmp / f"c{k}")
            except Exception as exc:  # a crash is a failure to report, not to hide
                fails.append((seed, fx or "none", f"crash: {type(exc).__name__}: {exc}"))
                continue
            t_loop.append(dt)
            want = sorted(MODEL_NAME[e] for e in fx.split(",") if e in MODEL_NAME)
            if added == want:
                ok += 1
            else:
                fails.append((seed, fx or "none", f"added {added}, true {want}"))
        rate = ok / max(n_loop, 1)
        print(f"randomized protocols: {ok}/{n_loop} right ({rate:.0%}); rig simulation {sum(t_gen) / n_loop:.1f} s, "
              f"loop {sum(t_loop) / max(len(t_loop), 1):.1f} s per campaign "
              f"(ratio to our rig's campaign {sum(t_loop) / max(len(t_loop), 1) / t_ours:.2f})")
        for f in fails:
            print(f"  seed {f[0]} ({f[1]}): {f[2]}")
        out["loop"] = {"campaigns": n_loop, "right": ok, "rate": rate, "failures": fails,
                       "loop_s_per_campaign": sum(t_loop) / max(len(t_loop), 1), "baseline_loop_s": t_ours}
        if n_pipeline:
            from solenoid_fmu.pipeline import run_pipeline

            ps45 = load_tables(ROOT / "fitting" / "ps45-demo" / "truth" / "maps")
            runs = []
            for k in range(n_pipeline):
                fx = ("hysteresis,friction", "heating,eddy-ladder")[k % 2]
                camp = tmp / f"p{k}"
                random_campaign(ps45, camp, fx, seed=2000 + k, max_samples=20000)
                t0 = time.perf_counter()
                s = run_pipeline(camp, tmp / f"p{k}-out", preset="quick", workers=2, progress=None)
                total = time.perf_counter() - t0
                stages = {key: round(v, 1) for key, v in s["times_s"].items() if key != "total"}
                print(f"pipeline (quick) on randomized PS45 campaign seed {2000 + k} ({fx}): {total:.0f} s, "
                      f"added {s['effects_added']}; stages {stages}")
                runs.append({"seed": 2000 + k, "effects": fx, "added": s["effects_added"], "total_s": total,
                             "stages_s": stages})
            out["pipeline"] = runs
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    args = [int(a) for a in sys.argv[1:3]]
    main(*args)

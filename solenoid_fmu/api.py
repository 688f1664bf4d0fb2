"""The public Python API: one verb per step of the data flow (README "Python API").

Every verb takes and returns SI values; paths may be strings or :class:`pathlib.Path`. The verbs
are thin: they name the entry point of each subpackage and fill the defaults a user expects (the
packaged PS45 geometry, the literature steel). ``import solenoid_fmu as sf`` exposes them lazily
(``sf.solve``, ``sf.build_maps`` ...), so importing the package stays cheap.

=================  =====================================================================
verb               what it does (subpackage)
=================  =====================================================================
``solve``          one FEM operating point: Psi [Wb], F [N] at (i [A], x [m])  (field)
``build_maps``     FEM sweep -> characteristic maps i_f(Psi, x), F(Psi, x)  (maps)
``save_maps``      write maps to a directory (``maps.npz`` + ``maps.json``)  (maps)
``load_maps``      read a maps directory  (maps)
``psi_at`` ...     query maps: ``psi_at(maps, i, x)``, ``force_at(maps, i, x)``,
                   ``i_f_at(maps, psi, x)``, ``force_psi_at(maps, psi, x)`` (paper eqs. 2-3)  (maps)
``read_recording`` read a recording (CSV, format v1; ``recordings.md``)  (measure)
``make_recording`` build a recording from SI arrays; ``write_recording`` writes it  (measure)
``flux_linkage``   Psi(t) and Psi(i) of a recording by paper eq. 4  (measure)
``identify``       B(H) of the steel from flux recordings, FEM + optimizer  (identification)
``export_fmu``     FMI 2.0 FMU from a maps directory, ``backend="python"|"c"``  (fmu)
``simulate``       drive an FMU with a recording's measured inputs  (fmu)
``validate``       FMU vs recordings: RMS and full-scale errors per signal  (loop)
``diagnose``       the effect the model lacks, from the FMU-vs-recording residual  (loop)
``improve``        add the diagnosed effects, fit them, export the improved FMU  (loop)
``run_rig``        the virtual test rig: a campaign of recordings from known maps  (rig)
``run_pipeline``   the main job on a campaign folder  (pipeline)
=================  =====================================================================
"""

from __future__ import annotations

from pathlib import Path

from .field import BHCurve, Geometry, Solution, load_geometry, load_material, solve_point
from .fmu import build_fmu, simulate_recording
from .identification import identify_from_recordings
from .loop import Diagnosis, improve, timed_cases, validate
from .loop import diagnose as _diagnose_cases
from .maps import build_maps, force_at, force_psi_at, i_f_at, load_maps, psi_at, save_maps
from .measure import flux_linkage, make_recording, read_recording, write_recording
from .pipeline import run_pipeline
from .realtime import load_tables
from .rig import Effects, run_campaign

__all__ = ["solve", "build_maps", "save_maps", "load_maps", "psi_at", "force_at", "i_f_at", "force_psi_at",
           "read_recording", "make_recording", "write_recording", "flux_linkage", "identify", "export_fmu",
           "simulate", "validate", "diagnose", "improve", "run_rig", "run_pipeline", "load_geometry",
           "load_material"]


def solve(i_A: float, x_m: float, *, geometry=None, material=None, mesh_size: float = 1.0) -> Solution:
    """Solve one operating point of the axisymmetric magnetostatic FEM (paper section 3).

    Parameters
    ----------
    i_A : float
        Coil current [A].
    x_m : float
        Armature working gap [m] (inside the geometry's stroke).
    geometry, material : path-like or loaded object, optional
        Default: the packaged PS45 geometry and the literature curve of its steel.
    mesh_size : float
        Mesh-size knob (1 = default accuracy; larger is coarser).

    Returns
    -------
    Solution
        ``psi_Wb`` [Wb], ``force_coenergy_N`` and ``force_stress_N`` [N] (co-energy and Maxwell
        stress; they agree to the discretization error), ``newton_iterations``.
    """
    geometry = geometry if isinstance(geometry, Geometry) else load_geometry(geometry)
    material = material if isinstance(material, BHCurve) else load_material(material)
    return solve_point(geometry, material, i_A, x_m, mesh_size)


def identify(recordings, *, geometry=None, start_material=None, out_csv=None, **options):
    """Identify the steel's initial magnetization curve B(H) from flux recordings (paper section 4).

    ``recordings`` are recording paths or :class:`~solenoid_fmu.measure.Recording` objects of any kinds; the
    ``flux`` ones are used. Further options (``mesh_size``, ``method``, ``n_currents``, ``report_dir``,
    ``progress``) as in :func:`solenoid_fmu.identification.identify_from_recordings`. Returns its
    ``IdentificationResult`` (``curve``: the identified B(H); ``out_csv`` writes it).
    """
    return identify_from_recordings(recordings, geometry=geometry, start_material=start_material,
                                    out_csv=out_csv, **options)


def export_fmu(maps_dir, dest_fmu, *, backend: str = "python", **options) -> Path:
    """Export the real-time model (paper eqs. 1-3 with the eddy term) as an FMI 2.0 FMU.

    ``backend="python"`` packs the model with pythonfmu (co-simulation); ``"c"`` generates C
    and compiles it (co-simulation and model exchange, no Python at run time). Returns the FMU path.
    """
    return build_fmu(maps_dir, dest_fmu, backend=backend, **options)


def simulate(fmu_path, recording, **options):
    """Drive an FMU (fmpy) with a recording's measured inputs; returns the simulated recording.

    ``drive="auto"`` takes the voltage as input where the recording has one, else the current.
    """
    return simulate_recording(fmu_path, recording, **options)


def diagnose(fmu_path, recordings, **options) -> Diagnosis:
    """Run the FMU on each recording and trace the residual to the effect the model lacks.

    Returns a ``Diagnosis``: ``ranking`` (effects by held-out explained residual share),
    ``verdict`` (the effect, or ``"unexplained"``). Options (``threshold`` ...) as in
    :func:`solenoid_fmu.loop.diagnose`.
    """
    cases = timed_cases(fmu_path, recordings)
    if not cases:
        raise ValueError("no recording has a signal to compare (voltage, current or force)")
    return _diagnose_cases(cases, **options)


def run_rig(maps_dir, out_dir, *, effects: str = "", seed: int = 0, **options) -> Path:
    """Run the virtual test rig: a campaign of recordings of the solenoid the maps describe.

    ``effects`` names what the truth has beyond the maps (comma list, e.g. ``"friction,noise"``;
    see ``solenoid-fmu rig --help``). Returns the campaign folder (``recordings/``, ``truth.json``).
    """
    run_campaign(load_tables(maps_dir), out_dir, effects=Effects.from_names(effects), seed=seed,
                 maps_dir=maps_dir, **options)
    return Path(out_dir)

"""solenoid-fmu: valve solenoid from geometry and test-rig recordings to a validated real-time FMU.

The public verbs (``solve``, ``build_maps``, ``load_maps``, ``read_recording``, ``identify``,
``export_fmu``, ``simulate``, ``validate``, ``diagnose``, ``improve``, ``run_rig``,
``run_pipeline`` ...) live in :mod:`solenoid_fmu.api` and are loaded on first use, so that
``import solenoid_fmu`` (and the command line's start-up) does not pull in the FEM and the FMU
tool chain. The subpackages follow the data flow (README "Package map"):
realtime -> field, measure -> identification, maps -> fmu, rig -> loop -> report -> pipeline -> cli.
"""

from ._version import __version__ as __version__  # the one version, re-exported

#: The public names (see :mod:`solenoid_fmu.api`); a test checks that this list equals ``api.__all__``.
__all__ = ["solve", "build_maps", "save_maps", "load_maps", "psi_at", "force_at", "i_f_at", "force_psi_at",
           "read_recording", "make_recording", "write_recording", "flux_linkage", "identify", "export_fmu",
           "simulate", "validate", "diagnose", "improve", "run_rig", "run_pipeline", "load_geometry",
           "load_material"]


def __getattr__(name: str):
    """Load a public verb from :mod:`solenoid_fmu.api` on first use (PEP 562)."""
    if name in __all__:
        from . import api  # lazy on purpose: the verbs import the FEM and the FMU tool chain

        return getattr(api, name)
    raise AttributeError(f"module 'solenoid_fmu' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))

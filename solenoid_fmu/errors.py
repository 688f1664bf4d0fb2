"""Exception hierarchy of solenoid-fmu: every error names the file, line or value at fault.

The command line prints ``str(error)`` and exits non-zero, so each message must stand on its own.
Errors that collect several problems (a geometry, a recording) carry them all in ``problems``.
"""

from __future__ import annotations


class SolenoidError(Exception):
    """Base class for every error the package raises on purpose."""


class ProblemsError(SolenoidError):
    """An error that lists every problem found, not only the first one.

    Parameters
    ----------
    what : str
        What was being checked (a file path or an object name).
    problems : list of str
        One human-readable line per problem.
    """

    def __init__(self, what: str, problems: list[str]):
        self.what = what
        self.problems = list(problems)
        super().__init__(self._message())

    def _message(self) -> str:
        lines = [f"{self.what}: {len(self.problems)} problem(s)"]
        lines += [f"  - {p}" for p in self.problems]
        return "\n".join(lines)


class GeometryError(ProblemsError):
    """A solenoid geometry file or object is invalid (every problem listed)."""


class MaterialError(SolenoidError):
    """A B(H) curve breaks the physics (names the point where it breaks) or is malformed."""


class MeshError(SolenoidError):
    """The mesh cannot be built or would invert somewhere in the stroke range."""


class SolverError(SolenoidError):
    """The nonlinear FEM did not converge; the message carries the residual history."""


class RecordingError(ProblemsError):
    """A test-rig recording is malformed (every problem listed with file and line)."""


class MapsError(SolenoidError):
    """A characteristic-map file is missing tables, has the wrong schema version, NaN, etc."""


class FmuInputError(SolenoidError):
    """An FMU or model input is invalid (NaN, R <= 0, unknown drive mode)."""


class FmuBuildError(SolenoidError):
    """An FMU cannot be built or fails validation (unknown backend, exporter failure, problems listed)."""

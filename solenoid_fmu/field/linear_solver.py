"""The direct solver of the FEM's Newton systems: symmetric positive definite, one sparsity pattern."""

from __future__ import annotations

import os

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..errors import SolverError

__all__ = ["SPDSolver", "LINEAR_SOLVER", "BACKENDS", "PARDISO_REFINEMENT_STEPS"]

#: Iterative refinement steps of PARDISO's solve (iparm(8); its default 2). The Cholesky factor of these SPD
#: systems solves them to a relative residual of 2.5e-12 without refinement, the same as with it (PS45, 1.5 A,
#: 1.5 mm), and each step costs a matrix product and another pair of triangular solves: a solve took 10 ms with
#: the default, 4.4 ms without (17k unknowns). Newton's residual is computed anew at every iterate and the
#: adjoint's accuracy needs only that of the Gauss-Newton Jacobian, so nothing rests on the refinement.
PARDISO_REFINEMENT_STEPS = 0


class SPDSolver:
    """Direct solver for the SPD Newton systems of one sparsity pattern.

    With ``pypardiso`` (MKL PARDISO, x86_64) the symbolic analysis (fill-reducing ordering) runs
    once per pattern and each Newton step does only the numeric Cholesky factorization and the
    solve (~0.05 s for 17k unknowns). Without it, SuperLU in symmetric mode (diagonal pivoting,
    minimum-degree ordering of A^T + A), several times slower.

    ``backend`` ("MKL PARDISO" or "SuperLU"; default ``LINEAR_SOLVER``) picks one explicitly: the two
    round differently, so running a solve through both shows whether a result depends on the rounding path.
    """

    def __init__(self, indptr: np.ndarray, indices: np.ndarray, n: int, backend: str | None = None):
        backend = LINEAR_SOLVER if backend is None else backend
        if backend not in BACKENDS:
            raise ValueError(f"linear solver {backend!r} is not available here: use one of {', '.join(BACKENDS)}"
                             + ("" if _pardiso else " ('MKL PARDISO' needs the package pypardiso, x86_64)"))
        self.backend = backend
        self.n = n
        rows = np.repeat(np.arange(n), np.diff(indptr))
        self.upper = indices >= rows
        cnt = np.bincount(rows[self.upper], minlength=n)
        self.u_indptr = np.concatenate([[0], np.cumsum(cnt)]).astype(np.int32)
        self.u_indices = indices[self.upper].astype(np.int32)
        self._ps = None
        if backend == "MKL PARDISO":
            self._ps = _pardiso.PyPardisoSolver(mtype=2)  # real symmetric positive definite
            self._analysed = False

    def solve(self, data: np.ndarray, indices: np.ndarray, indptr: np.ndarray, b: np.ndarray) -> np.ndarray:
        """The solution of K x = b; :class:`SolverError` (one line) when K or b is not finite or the
        factorization fails (e.g. a current so large that the stiffness overflows)."""
        if not (np.all(np.isfinite(b)) and np.all(np.isfinite(data))):
            raise SolverError("the FEM system is not finite (current or field beyond floating point range)")
        try:
            return self._solve(data, indices, indptr, b)
        except SolverError:
            raise
        except Exception as exc:  # PyPardisoError, SuperLU's RuntimeError: a failed factorization
            raise SolverError(f"the linear solver ({self.backend}) failed: {type(exc).__name__}: "
                              f"{str(exc).splitlines()[0] if str(exc) else ''}") from None

    def _solve(self, data: np.ndarray, indices: np.ndarray, indptr: np.ndarray, b: np.ndarray) -> np.ndarray:
        if self._ps is None:
            K = sp.csc_matrix((data, indices, indptr), shape=(self.n, self.n))  # symmetric: CSR = CSC^T
            lu = splu(K, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
            return lu.solve(b)
        A = sp.csr_matrix((data[self.upper], self.u_indices, self.u_indptr), shape=(self.n, self.n))
        A.has_sorted_indices = True
        if not self._analysed:
            self._ps.set_phase(11)
            self._ps._call_pardiso(A, b)  # with iparm(1) = 0 PARDISO writes its defaults into iparm here
            self._ps.set_iparm(8, PARDISO_REFINEMENT_STEPS)
            self._analysed = True
        self._ps.set_phase(22)
        self._ps._call_pardiso(A, b)
        self._ps.set_phase(33)
        return self._ps._call_pardiso(A, b)


try:  # optional accelerator, see SPDSolver
    import pypardiso as _pardiso
except ImportError:  # pragma: no cover - depends on the platform
    _pardiso = None


def _locate_mkl_once() -> None:
    """Find MKL's runtime library once per process, at import, and tell pypardiso where it is.

    Without ``PYPARDISO_MKL_RT`` every ``PyPardisoSolver()`` globs the whole environment for the library
    (0.3 s, once per FEM solver: minutes over the test suite). The variable is set once here, in the
    importing thread, before this module has started any MKL thread, and never changed again (an earlier
    version set and removed it around every construction while other threads ran, which is not
    thread-safe: a subprocess died in glibc's allocator). A value the user set is kept."""
    if _pardiso is None or os.environ.get("PYPARDISO_MKL_RT"):
        return
    try:
        name = getattr(_pardiso.PyPardisoSolver(mtype=2).libmkl, "_name", None)
    except Exception:  # pragma: no cover - no MKL runtime: SPDSolver reports it when used
        return
    if name:
        os.environ["PYPARDISO_MKL_RT"] = name


_locate_mkl_once()

#: The direct solver of the Newton systems on this machine: "MKL PARDISO" or "SuperLU".
LINEAR_SOLVER = "MKL PARDISO" if _pardiso is not None else "SuperLU"
#: The backends ``SPDSolver`` can use on this machine.
BACKENDS = ("MKL PARDISO", "SuperLU") if _pardiso is not None else ("SuperLU",)

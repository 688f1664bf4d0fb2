"""BLAS, MKL and OpenMP single-threaded around the FEM's solves (``threadpoolctl``).

One :class:`threadpoolctl.ThreadpoolController` for the process, built at the first use (after numpy, scipy
and pypardiso have loaded their libraries): ``threadpool_limits`` inspects the loaded libraries anew on every
call (0.36 ms, about 2000 times per identification); the controller's ``limit`` takes 0.02 ms.
"""

from __future__ import annotations

from threadpoolctl import ThreadpoolController

__all__ = ["single_threaded"]

_CONTROLLER: list = []


def single_threaded():
    """Context manager: the thread pools of BLAS, MKL and OpenMP limited to one thread inside it."""
    if not _CONTROLLER:
        with ThreadpoolController().limit(limits=1):  # MKL loads its OpenMP runtime at its first limit: seen next
            pass
        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0].limit(limits=1)

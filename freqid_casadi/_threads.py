"""BLAS threads during fits (root helper)."""

import sys
import threading

__all__ = ["single_threaded_blas"]

_lock = threading.Lock()
_controller = [None, -1]        # (threadpoolctl controller, len(sys.modules) when made)


def _blas_controller():
    """A ``threadpoolctl.ThreadpoolController`` of the loaded BLAS libraries, made again
    only when a module was imported since (a new extension module is how a new BLAS gets
    loaded): finding the libraries costs 1.6 ms, which ``threadpool_limits`` paid at every
    call, twice per fit (the fit and its covariance); limiting through a kept controller
    costs 0.02 ms."""
    from threadpoolctl import ThreadpoolController

    with _lock:
        if _controller[1] != len(sys.modules):
            _controller[0] = ThreadpoolController()
            _controller[1] = len(sys.modules)
        return _controller[0]


def single_threaded_blas():
    """BLAS limited to one thread: the stage matrices are small (n x 2M), and OpenBLAS
    threads oversubscribe the cores when several fits run at once (12x slower measured).

    Returns
    -------
    threadpoolctl limiter
        Limits at once; restores the previous limits on ``restore_original_limits()`` or at
        the end of a ``with`` block.
    """
    import scipy.linalg  # noqa: F401  (load scipy's BLAS now: limits apply to loaded ones)

    return _blas_controller().limit(limits=1, user_api="blas")

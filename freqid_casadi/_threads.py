"""BLAS threads during fits (root helper)."""

__all__ = ["single_threaded_blas"]


def single_threaded_blas():
    """BLAS limited to one thread: the stage matrices are small (n x 2M), and OpenBLAS
    threads oversubscribe the cores when several fits run at once (12x slower measured)."""
    import scipy.linalg  # noqa: F401  (load scipy's BLAS now: limits apply to loaded ones)
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")

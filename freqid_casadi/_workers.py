"""Worker processes (root helper): ``fit_many``, ``fit(n_jobs=...)``, the survey's orders
and the bootstrap's replicates.

A forked worker starts with the package already imported; a spawned one (joblib's loky,
multiprocessing's "spawn") spends about a second importing CasADi and SciPy, as long as a
whole fit of a few hundred points. Forking is safe here only where the platform has it
and this process runs no other Python thread (a fork copies no lock another thread holds);
:func:`can_fork` says so, and callers keep another path for the rest.
"""

import contextlib
import contextvars
import multiprocessing
import os
import threading
import warnings

from .errors import OptionError

__all__ = ["can_fork", "fork_submit", "collect", "local_map", "allow_jobs", "forked_map"]

_LIMITS = None

#: Worker processes the running call (one fit) may use for its independent parts
#: (:func:`forked_map`); 1 in a worker.
_JOBS = contextvars.ContextVar("worker_jobs", default=1)


@contextlib.contextmanager
def allow_jobs(n_jobs):
    """Within this context, :func:`forked_map` uses up to ``n_jobs`` worker processes."""
    token = _JOBS.set(int(n_jobs))
    try:
        yield
    finally:
        _JOBS.reset(token)


def _in_worker(fn, *args):
    """``fn(*args)`` in a forked worker, which starts no workers of its own."""
    _JOBS.set(1)
    return fn(*args)


def forked_map(fn, jobs, n_jobs=None):
    """``[fn(*args) for args in jobs]`` in forked worker processes, or None where they
    would not help or are not safe: fewer than 2 jobs or workers, or no fork
    (:func:`can_fork`); the caller then runs the jobs itself.

    Parameters
    ----------
    fn : callable
        A module-level function (it and its arguments are pickled).
    jobs : list of tuple
    n_jobs : int, optional
        Worker processes; default those :func:`allow_jobs` allows (1 outside it).

    Returns
    -------
    list or None
    """
    n_jobs = _JOBS.get() if n_jobs is None else int(n_jobs)
    if n_jobs < 2 or len(jobs) < 2 or not can_fork():
        return None
    pool, futures = fork_submit(n_jobs, _in_worker, [(fn, *args) for args in jobs])
    return list(collect(pool, futures))              # (the workers exit here)


def can_fork():
    """True where forked workers are safe: the platform has ``fork`` and this process runs
    no Python thread besides the main one."""
    return ("fork" in multiprocessing.get_all_start_methods()
            and threading.active_count() == 1)


def _worker_init():
    """Forked worker's initializer: one BLAS thread for the worker's life (a fit limits its
    own stages; the rest then does not oversubscribe the cores either), and Python's own
    signal handling instead of a command's inherited one: SIGTERM (from :func:`collect`
    when the caller stops) ends the worker quietly; Ctrl-C, which reaches the whole process
    group, stops the running fit, as in a fit of one's own."""
    import signal

    from ._threads import single_threaded_blas

    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    global _LIMITS
    _LIMITS = single_threaded_blas()


def fork_submit(n_workers, fn, jobs):
    """Start ``n_workers`` forked workers and submit ``fn(*args)`` for each ``args`` of
    ``jobs`` (the workers fork at once, before the caller starts any thread).

    Parameters
    ----------
    n_workers : int
        Worker processes (at most ``len(jobs)`` are started).
    fn : callable
        A module-level function (it and its arguments are pickled).
    jobs : list of tuple

    Returns
    -------
    (concurrent.futures.ProcessPoolExecutor, list of Future)
        Hand both to :func:`collect`.
    """
    from concurrent.futures import ProcessPoolExecutor

    pool = ProcessPoolExecutor(max(1, min(int(n_workers), len(jobs))),
                               multiprocessing.get_context("fork"), initializer=_worker_init)
    with warnings.catch_warnings():
        # Python >= 3.12 warns when forking a process with native threads (OpenBLAS's pool):
        # OpenBLAS stops its threads around fork itself, and no Python thread runs.
        warnings.filterwarnings("ignore", "This process .* is multi-threaded",
                                DeprecationWarning)
        futures = [pool.submit(fn, *args) for args in jobs]
    return pool, futures


def collect(pool, futures):
    """The results of ``futures`` in order, each as soon as it is done (a generator); on an
    exception or an interruption the pending jobs are cancelled and the workers stopped
    (no orphan keeps working).

    Parameters
    ----------
    pool : concurrent.futures.ProcessPoolExecutor
    futures : list of Future
        As :func:`fork_submit` returns them.
    """
    try:
        for future in futures:
            yield future.result()
    except GeneratorExit:
        # closed by its caller: workers still busy are stopped, idle ones exit normally
        if not all(f.done() for f in futures):
            _terminate(pool)
        raise
    except BaseException:
        _terminate(pool)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def local_map(fn, jobs, n_jobs):
    """``fn(*args)`` for each ``args`` of ``jobs`` in ``n_jobs`` local worker processes,
    yielded in the order of ``jobs`` as each is done: forked workers where
    :func:`can_fork` (they fork here, at the call, before the caller starts a thread such
    as a progress bar's), else joblib's loky backend; one BLAS thread per worker either way.

    Parameters
    ----------
    fn : callable
        A module-level function (it and its arguments are pickled).
    jobs : list of tuple
    n_jobs : int
        Worker processes; a negative number counts as joblib does (-1: every core, -2:
        all but one).

    Returns
    -------
    iterator
    """
    if can_fork():
        workers = n_jobs if n_jobs > 0 else max(1, (os.cpu_count() or 1) + 1 + n_jobs)
        return collect(*fork_submit(workers, fn, jobs))
    return _run_joblib(fn, jobs, n_jobs)


def _run_joblib(fn, jobs, n_jobs):
    try:
        from joblib import Parallel, delayed, parallel_config
    except ImportError:
        raise OptionError("n_jobs > 1 needs joblib: pip install joblib (or use n_jobs=1)") \
            from None
    # inner_max_num_threads=1: BLAS/OpenMP at one thread per worker
    with parallel_config(backend="loky", inner_max_num_threads=1):
        yield from Parallel(n_jobs=min(n_jobs, len(jobs)) if n_jobs > 0 else n_jobs,
                            return_as="generator")(delayed(fn)(*args) for args in jobs)


def _terminate(pool):
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        proc.terminate()

"""Many fits at once: :func:`fit_many` over local processes or a Dask cluster (layer L4).

Each dataset is fitted by :func:`freqid_casadi.fitting.fit.fit` inside the worker, so every worker
builds its own CasADi functions (they are not shared or pickled) and keeps BLAS at one thread
(``fit`` wraps itself in ``threadpoolctl``). A dataset that fails (a malformed file, too few
points for the structure, a solver exception) gives a :class:`BatchItem` with its error
message; the other fits go on. Option errors, which would fail every dataset alike, are
raised once before any fit.

Local parallelism forks worker processes where the platform can (Linux), so a worker
starts with the package already imported (a spawned one spends about a second importing
CasADi and SciPy: with 128 fits of 0.1 s that kept 2 jobs well below a speed-up of 2);
elsewhere, or when the calling process runs other threads, it uses joblib's ``loky``
backend. A ``scheduler`` address runs the fits on a Dask ``distributed`` cluster. Both are
imported only when needed; Dask is an optional extra (``pip install freqid_casadi[dask]``).
"""

import inspect
import os
import warnings
from dataclasses import dataclass

from ..core.data import FrequencyData
from ..io import parse_band, parse_columns, parse_freq_unit
from ..io.loaders import load
from ..errors import DataError, OptionError, StructureError
from .fit import FitResult, fit
from .verdict import FitStatus
from ..core.model import BASES, Structure
from ..options import LEGACY_KEYWORDS, LoopOptions, legacy_message, solver_options
from .._progress import channel, check_progress
from .._validate import check_jobs
from .._workers import local_map

__all__ = ["fit_many", "BatchItem", "BATCH_STATUSES"]

#: Values of :attr:`BatchItem.status`: a fit's :class:`~.verdict.FitStatus`, or "error".
BATCH_STATUSES = tuple(s.value for s in FitStatus) + ("error",)

_FIT_OPTIONS = frozenset(p for p in inspect.signature(fit).parameters
                         if p not in ("data_or_omega", "response"))


@dataclass(frozen=True, eq=False)
class BatchItem:
    """Outcome of one dataset of :func:`fit_many`.

    Attributes
    ----------
    name : str
        The dataset's name (``FrequencyData.name``, else the file name without its
        extension, else ``"data<k>"``).
    result : FitResult or None
        The fit, or None if it failed.
    error : str or None
        ``"<ExceptionType>: <message>"`` if the fit failed, else None.
    status : FitStatus or "error"
        The fit's :attr:`FitResult.status <freqid_casadi.fitting.fit.FitResult.status>`
        ("ok", "poor-fit" or "not-converged": a ``str`` enum, so ``item.status == "ok"``
        works), or "error" if there is no result (see ``error``).
    source : str or None
        The file the data came from, if it was given as a path.
    """

    name: str
    result: FitResult = None
    error: str = None
    status: str = "error"
    source: str = None

    @property
    def ok(self):
        """True if a model was fitted (converged or not)."""
        return self.result is not None


def _check_options(options):
    for name in options:
        if name in LEGACY_KEYWORDS:
            raise TypeError(legacy_message("fit_many", name, options[name]))
    unknown = sorted(set(options) - _FIT_OPTIONS)
    if unknown:
        raise OptionError(f"unknown fit option(s) {', '.join(map(repr, unknown))}; "
                          f"choose from {', '.join(sorted(_FIT_OPTIONS))}")
    if "n_sections" not in options:
        raise OptionError("n_sections is missing: call fit_many(datasets, n_sections=N, ...)")
    if options.get("basis", "second-order") not in BASES:
        raise OptionError(f"unknown basis {options['basis']!r}; choose one of "
                          f"{', '.join(BASES)}")
    solver_options(options.get("method", "ipopt"))       # OptionError on a bad method
    n = Structure(options["n_sections"]).n_sections        # StructureError if not an int
    if n < 1:
        raise StructureError(f"n_sections must be >= 1, got {n}")
    if not isinstance(options.get("loop", LoopOptions()), LoopOptions):
        raise OptionError(f"loop must be a LoopOptions, got {type(options['loop']).__name__}")


def _name_of(k, item):
    if isinstance(item, FrequencyData):
        return item.name or f"data{k}", None
    if isinstance(item, (str, os.PathLike)):
        path = os.fspath(item)
        return os.path.splitext(os.path.basename(path))[0], path
    raise DataError(f"datasets[{k}] must be a FrequencyData or a file path, got "
                    f"{type(item).__name__}")


def _fit_one(name, item, options, load_options=None):
    """Worker: load (if a path) and fit one dataset; never raises a FreqidError."""
    source = None if isinstance(item, FrequencyData) else os.fspath(item)
    try:
        # a load option that does not apply to this file (columns= of a .npz) is this
        # file's error, as a file it cannot read: fit_many checked the options' forms
        data = item if source is None else load(source, name, **(load_options or {}))
    except Exception as exc:  # noqa: BLE001 - one failing dataset must not stop the batch
        return _failed(name, exc, source)
    try:
        result = fit(data, **options)
    except OptionError:
        raise                                   # the same for every dataset: not per item
    except Exception as exc:  # noqa: BLE001
        return _failed(name, exc, source)
    return BatchItem(name, result, None, FitStatus(result.status), source)


def _failed(name, exc, source):
    """The BatchItem of a dataset that could not be loaded or fitted."""
    message = " ".join(str(exc).split())
    return BatchItem(name, None, f"{type(exc).__name__}: {message}", "error", source)


def _fit_one_held(name, item, options, load_options=None):
    """Worker: :func:`_fit_one` with its warnings caught; returns ``(BatchItem, [(category,
    message), ...])`` so that the caller re-issues them in its own process (a worker
    process would print them in Python's raw format, beside the command's own lines)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        item = _fit_one(name, item, options, load_options)
    said = [(w.category, str(w.message)) for w in caught]
    return item, list(dict.fromkeys(said))


def _reissue(held):
    """The BatchItems of ``held`` (``_fit_one_held`` results), their warnings re-issued here
    with the dataset's name in front."""
    for item, said in held:
        for category, message in said:
            warnings.warn(f"{item.name}: {message}", category, stacklevel=3)
    return [item for item, _ in held]


def fit_many(datasets, *, n_jobs=1, scheduler=None, load_options=None, progress=False,
             **options):
    """Fit every dataset with the same options, in parallel processes or on a cluster.

    Parameters
    ----------
    datasets : iterable of FrequencyData or str or os.PathLike
        The data, or paths of ``.csv``/``.npz`` files (loaded in the worker, so a bad file
        is reported like a failed fit).
    n_jobs : int
        Local worker processes (forked on Linux, else joblib's ``loky`` backend); 1 fits in
        this process.
        Ignored when ``scheduler`` is given.
    scheduler : str or distributed.Client, optional
        Address of a Dask distributed scheduler (e.g. ``"tcp://127.0.0.1:8786"``) or a
        connected ``Client``; the fits then run on its workers.
    load_options : dict, optional
        Keywords of :func:`freqid_casadi.io.loaders.load` for the file paths (``freq_unit``,
        ``columns``).
    progress : bool, "lines" or callable, optional
        True draws a bar on a terminal (elsewhere a line per 30 s of a long run), "lines"
        writes a line per dataset to stderr, a callable receives each :class:`BatchItem` as
        it is done.
    **options
        Keyword arguments of :func:`freqid_casadi.fitting.fit.fit` (``n_sections`` is required).

    Returns
    -------
    list of BatchItem
        One per dataset, in the input order.

    Raises
    ------
    TypeError
        A keyword fit() no longer takes (the message names its option object), or
        ``jobs=`` (now ``n_jobs=``).
    OptionError
        Unknown or invalid options, bad ``jobs``, or ``scheduler`` given but Dask is not
        installed.
    StructureError
        Invalid ``n_sections``.
    DataError
        A dataset that is neither data nor a path.

    Notes
    -----
    Results do not depend on ``n_jobs`` or the scheduler: each fit is deterministic and runs
    with single-threaded BLAS, so the model JSON equals that of a serial run.
    """
    if "jobs" in options:
        raise TypeError("fit_many() takes n_jobs=, not jobs= (one spelling for the number of "
                        "worker processes across the package); pass n_jobs="
                        f"{options['jobs']!r}")
    _check_options(options)
    check_jobs(n_jobs)
    progress = check_progress(progress, "each BatchItem")
    if load_options is not None and not isinstance(load_options, dict):
        raise OptionError(f"load_options must be a dict of load() keywords or None, got "
                          f"{load_options!r:.80}")
    known = set(inspect.signature(load).parameters) - {"path", "name"}
    unknown = sorted(set(load_options or {}) - known)
    if unknown:
        raise OptionError(f"unknown load option(s) {', '.join(map(repr, unknown))}; choose "
                          f"from {', '.join(sorted(known))}")
    for key, parse in (("freq_unit", parse_freq_unit), ("columns", parse_columns),
                       ("band", parse_band)):
        parse((load_options or {}).get(key))     # OptionError once, not per file
    if isinstance(datasets, (str, os.PathLike, FrequencyData)):
        datasets = [datasets]
    try:
        items = list(datasets)
    except TypeError:
        raise DataError(f"datasets must be a list of FrequencyData or file paths, got "
                        f"{type(datasets).__name__}") from None
    names = [_name_of(k, item)[0] for k, item in enumerate(items)]
    if not items:
        return []
    local = None
    if scheduler is None and n_jobs > 1 and len(items) > 1:   # before the bar's thread
        local = local_map(_fit_one_held, [(n, item, options, load_options)
                                          for n, item in zip(names, items)], n_jobs)
    with channel(progress, _item_line, total=len(items), unit="file") as emit:
        if scheduler is not None:
            held = _run_dask(scheduler, names, items, options, load_options)
        elif local is not None:
            held = local
        else:
            held = (_fit_one_held(n, item, options, load_options)
                    for n, item in zip(names, items))
        done = []
        for pair in held:                    # in input order, each as soon as it is done
            done.append(pair)
            emit(pair[0])
    return _reissue(done)


def _item_line(item):
    """One line of text for a finished dataset (``progress="lines"``)."""
    if item.result is None:
        return f"{item.name}: {item.status} ({item.error})"
    return (f"{item.name}: {item.status}, max rel. error {item.result.max_rel_error:.3e}, "
            f"{item.result.wall_time:.1f} s")


def _run_dask(scheduler, names, items, options, load_options=None):
    try:
        from distributed import Client
    except ImportError:
        raise OptionError("scheduler needs Dask: pip install freqid_casadi[dask] "
                          "(dask and distributed)") from None
    own = not isinstance(scheduler, Client)
    if own and not isinstance(scheduler, str):
        raise OptionError(f"scheduler must be an address string or a distributed.Client, got "
                          f"{type(scheduler).__name__}")
    try:
        client = Client(scheduler, set_as_default=False) if own else scheduler
    except (OSError, TimeoutError, ValueError) as exc:
        raise OptionError(f"cannot connect to the Dask scheduler {scheduler!r}: {exc}; check "
                          "the address (e.g. tcp://127.0.0.1:8786)") from None
    try:
        futures = client.map(_fit_one_held, names, items, options=options,
                             load_options=load_options, pure=False)
        return client.gather(futures)
    finally:
        if own:
            client.close()

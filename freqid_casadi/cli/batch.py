"""The ``freqid batch`` command: fit every data file of a folder (layer L6).

::

    freqid batch DIR --out DIR --sections N [--jobs N] [--scheduler ADDRESS]
                 [--integrator] [--no-delay] [--basis B] [--method M] [--final-max-iter N]
                 [--tol X] [--force]

Every data file directly inside ``DIR`` (``.csv``, ``.npz``, ``.mat``, ``.uff``/``.unv``,
Touchstone ``.sNp``/``.ts``; ``--parameter``, ``--record`` apply to each) is fitted with the
same options by
:func:`freqid_casadi.fitting.batch.fit_many`. The output folder holds::

    summary.md      first line: the command; the count of each status; one table row per
                    file, led by its status
    summary.csv     status (ok, poor-fit, not-converged or error), file, name, order,
                    max/RMS relative error, ..., message, error, model
    models/<name>.json   the model of every file that was fitted (named in the ``model``
                    column: the file's stem, or its whole name where stems collide)

It is built in a temporary sibling folder and renamed into place when complete (nothing is
left behind on an error or Ctrl-C); an existing ``--out`` is refused before any fit unless
``--force``. Exit code 0 if every file was fitted and converged (status "ok" or "poor-fit"), 1 if a
file failed or did not converge (the summary says which), 2 on a usage, option or folder error.

Registered in :data:`freqid_casadi.cli.app.COMMANDS` (its :func:`add_cli` and :func:`run_cli`).
"""

import collections
import dataclasses
import math
import os
import stat
import warnings

from .common import (NOISE_WEIGHTS, cli_words, load_options, loop_option, method_option,
                     notes_to_stderr, refuse_flags)
from .._textio import atomic_write_text, csv_row, one_line
from ..fitting.batch import BATCH_STATUSES, fit_many
from .common import (_add_final_max_iter, _add_input, _add_model_arguments,  # the CLI's
                     _positive_int, _record)                             # own helpers
from ..report.outputs import MARKER
from ..errors import DataError, OptionError
from ..fitting.fit import METHODS
from ..io.loaders import is_touchstone
from ..report.formatting import number as _num
from ..report.folder import check_out_dir, generated_by_line, markdown_table, report_folder

__all__ = ["add_cli", "run_cli", "write_batch_report", "data_files", "scan_folder",
           "BATCH_FILES"]

#: Files of a batch output folder (besides models/).
BATCH_FILES = (MARKER, "summary.csv", "summary.md")

#: The data files batch reads (and Touchstone ``.sNp``/``.ts``, :func:`is_touchstone`).
_SUFFIXES = (".csv", ".npz", ".mat", ".uff", ".unv")
#: Text files ``freqid fit`` reads but batch does not (a folder's notes are text too):
#: named in a warning and in the summary when skipped.
_OTHER_DATA = (".txt", ".dat", ".tsv")

_COLUMNS = ("status", "file", "name", "n_sections", "order", "max_rel_error",
            "rms_rel_error", "delay", "nit", "wall_time", "message", "error", "model")
#: BatchItem statuses whose fit converged (the exit code is 0 when every file's is one).
_CONVERGED = ("ok", "poor-fit")


def add_cli(subparsers):
    """Add the ``batch`` subcommand to ``subparsers``; returns its parser.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The result of ``ArgumentParser.add_subparsers``.
    """
    p = subparsers.add_parser(
        "batch", help="fit every data file of a folder",
        description="Fit G_N(s) = exp(-hs) K [1/s] P_N(s) to every data file (.csv, .npz, "
                    ".mat, .uff/.unv, Touchstone .sNp/.ts) in a folder with the same "
                    "options, in parallel processes (--jobs) or on a Dask cluster "
                    "(--scheduler), and write per-file models and a summary.")
    _add_input(p, "folder", "DIR", "folder of data files (.csv, .npz, .mat, .uff/.unv, "
               "Touchstone .sNp/.ts)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output folder to create (must not exist unless --force)")
    p.add_argument("--sections", type=_positive_int, required=True, metavar="N",
                   help="number of sections N >= 1")
    p.add_argument("--jobs", "--n-jobs", dest="jobs", type=_positive_int, default=1,
                   metavar="N", help="local worker processes (default 1; n_jobs of fit_many)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="Dask scheduler address (e.g. tcp://127.0.0.1:8786); needs "
                        "pip install freqid_casadi[dask]")
    p.add_argument("--record", type=_record, metavar="K",
                   help="which frequency-response record of each UFF file (0-based), or run "
                        "of an LTspice export")
    p.add_argument("--parameter", metavar="S21",
                   help="which parameter of each Touchstone file or network analyser's CSV "
                        "(default S11), or which response variable of each .mat file")
    _add_model_arguments(p, integrator=False)
    p.add_argument("--method", choices=METHODS, default="ipopt",
                   help="stage solver (default ipopt)")
    _add_final_max_iter(p)
    p.add_argument("--weights", choices=(NOISE_WEIGHTS,),
                   help="'noise': weights estimated from each file's data, for an "
                        "analyser's noise floor (fit's weights='noise'; twice the time)")
    p.add_argument("--force", action="store_true",
                   help="replace an existing output folder (after the new one is complete)")
    return p


def data_files(folder):
    """Sorted paths of the data files directly inside ``folder``: ``.csv``, ``.npz``,
    ``.mat``, ``.uff``/``.unv`` and Touchstone ``.sNp``/``.ts`` regular files.

    A symbolic link is followed only if its target lies inside ``folder``; other links,
    FIFOs, devices and sub-folders are skipped (a ``UserWarning`` names each skipped link,
    and one names the text tables batch does not read, ``.txt``, ``.dat``, ``.tsv``: a
    folder's notes are text too).

    Parameters
    ----------
    folder : str or path-like
        The folder to list.

    Raises
    ------
    DataError
        If ``folder`` is missing, not a folder, unreadable or holds no data file.
    """
    paths, skipped = scan_folder(folder)
    _warn_skipped(skipped)
    return paths


def _warn_skipped(skipped):
    for name, why in skipped:
        warnings.warn(f"skipped {name!r}: {why}", UserWarning, stacklevel=3)


def scan_folder(folder):
    """:func:`data_files` without the warnings: ``(paths, skipped)``, ``skipped`` the
    ``(file name, reason)`` of each data-like file not fitted (a text table, a link out of
    the folder), for the summary.

    Parameters
    ----------
    folder : str or path-like

    Returns
    -------
    (list of str, list of (str, str))

    Raises
    ------
    DataError
        As :func:`data_files`.
    """
    folder = os.fspath(folder)
    if not os.path.exists(folder):
        raise DataError(f"data folder not found: {folder!r}; check the path")
    if not os.path.isdir(folder):
        raise DataError(f"{folder!r} is a file, not a folder; use 'freqid fit' for one file")
    try:
        names = sorted(os.listdir(folder))
    except OSError as exc:
        raise DataError(f"cannot list {folder!r}: {exc.strerror}") from None
    real_folder = os.path.realpath(folder)
    paths, skipped = [], []
    for n in names:
        p = os.path.join(folder, n)
        if n.lower().endswith(_OTHER_DATA):
            skipped.append((n, "a text table freqid batch does not read (a folder's notes "
                               "are text too); fit it with freqid fit, or save it as .csv"))
            continue
        if not n.lower().endswith(_SUFFIXES) and not is_touchstone(n):
            continue
        real = os.path.realpath(p)
        if os.path.islink(p) and os.path.dirname(real) != real_folder:
            skipped.append((n, f"a symbolic link to {real!r}, outside the data folder"))
            continue
        if stat.S_ISREG(_mode(p)):
            paths.append(p)
    if not paths:
        raise DataError(f"no data files (.csv, .npz, .mat, .uff/.unv, Touchstone .sNp/.ts) "
                        f"in {folder!r}")
    return paths, skipped


def _mode(path):
    try:
        return os.stat(path).st_mode
    except OSError:
        return 0


def _unique_names(paths):
    """Model file names (without ``.json``), unique even on a case-insensitive file system:
    the stem, or the whole file name where two stems collide, then ``-2``, ``-3`` ...; a name
    that is empty or starts with a dot gets a ``data`` prefix."""
    bases = [os.path.basename(p) for p in paths]
    names = [os.path.splitext(b)[0] for b in bases]
    for _ in range(2):          # a.csv, a.npz, a.csv.npz: a, a -> a.csv, a.csv -> a.csv.npz
        folded = [n.casefold() for n in names]
        names = [n if folded.count(n.casefold()) == 1 else b for n, b in zip(names, bases)]
    taken, out = set(), []
    for name in names:
        name = name if name and not name.startswith(".") else f"data{name}"
        candidate, k = name, 1
        while candidate.casefold() in taken:
            k += 1
            candidate = f"{name}-{k}"
        taken.add(candidate.casefold())
        out.append(candidate)
    return out


def _row(item, file_name, model_file):
    r = item.result
    if r is None:
        return dict(file=file_name, model=None, name=item.name, status=str(item.status),
                    n_sections=None, order=None, max_rel_error=None, rms_rel_error=None,
                    delay=None, nit=None, wall_time=None, message=None, error=item.error)
    return dict(file=file_name, model=model_file, name=item.name, status=str(item.status),
                n_sections=r.model.n_sections, order=r.model.order,
                max_rel_error=r.max_rel_error, rms_rel_error=r.rms_rel_error,
                delay=r.model.delay, nit=r.nit, wall_time=r.wall_time, message=r.message,
                error=None)


def _csv_value(v):
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else None
    return v


def write_batch_report(items, files, out_dir, *, command, force=False, skipped=()):
    """Write the batch output folder (see the module docstring); returns its absolute path.

    Parameters
    ----------
    items : list of BatchItem
    files : list of str
        The data file of each item (same order).
    out_dir : str or os.PathLike
    command : str
        Named on the first line of summary.md.
    force : bool
        Replace an existing ``out_dir`` once the new folder is complete.
    skipped : sequence of (str, str)
        Files of the folder not fitted and why (:func:`scan_folder`), listed in
        summary.md.
    """
    path = check_out_dir(out_dir, force)
    with report_folder(out_dir, force) as (tmp, _):
        models = os.path.join(tmp, "models")
        os.mkdir(models)
        rows = []
        for item, model_name, f in zip(items, _unique_names(files), files):
            model_file = f"models/{model_name}.json"
            if item.result is not None:
                item.result.model.save(os.path.join(tmp, model_file))
            rows.append(_row(item, os.path.basename(f), model_file))
        lines = [csv_row(_COLUMNS)]
        lines += [csv_row([_csv_value(r[c]) for c in _COLUMNS]) for r in rows]
        atomic_write_text(os.path.join(tmp, "summary.csv"), "\n".join(lines) + "\n")
        atomic_write_text(os.path.join(tmp, "summary.md"), _markdown(rows, command, skipped))
    return path


def _markdown(rows, command, skipped=()):
    counts = ", ".join(f"{sum(r['status'] == s for r in rows)} {s}" for s in BATCH_STATUSES)
    table = markdown_table(
        [(r["status"], r["file"], r["order"], _num(r["max_rel_error"]),
          _num(r["rms_rel_error"]), _num(r["delay"]), r["nit"],
          _num(r["wall_time"], 3), r["message"] or r["error"], r["model"]) for r in rows],
        ("status", "file", "order", "max rel. error", "RMS rel. error", "delay (s)",
         "iterations", "time (s)", "message", "model file"), align="llrrrrrrll")
    lines = [generated_by_line(command), "", "# Batch fit", "",
             f"{len(rows)} files: {counts}.", "", table, ""]
    if skipped:
        lines += ["Not fitted:", ""] + [f"- `{one_line(n)}`: {why}" for n, why in skipped]
        lines += [""]
    return "\n".join(lines)


def _as_flag_refusal(item, opts):
    """``item`` whose error is a load option refused for its file (``columns=`` of a .npz)
    with the refusal spelt as the command line's option (``--columns``): load() refuses
    before it reads the file, so a refusal here was that item's error."""
    if item.result is not None or not item.source:
        return item
    try:
        refuse_flags(item.source, opts)
    except OptionError as exc:
        return dataclasses.replace(item, error=f"OptionError: {one_line(str(exc))}")
    return item


def run_cli(args, command):
    """Run ``freqid batch`` from parsed ``args``; returns the exit code (0, or 1 if a file
    failed or did not converge). FreqidError/OSError propagate to ``cli.main`` (exit 2).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed ``freqid batch`` arguments.
    command : str
        The command line, named on the report's first line.
    """
    files, skipped = scan_folder(args.folder)
    _warn_skipped(skipped)
    check_out_dir(args.out, args.force)              # before the (long) fits
    opts = load_options(args)
    with notes_to_stderr():                          # zero-frequency rows dropped, ...
        items = fit_many(files, n_jobs=args.jobs, scheduler=args.scheduler,
                         load_options=opts,
                         n_sections=args.sections, integrator=args.integrator,
                         delay=args.delay, basis=args.basis, method=method_option(args),
                         tol=args.tol, **loop_option(args),
                         **({"weights": args.weights} if args.weights else {}))
    items = [_as_flag_refusal(item, opts) for item in items]
    # the summary names the text tables not fitted, not a link's target outside the folder
    tables = [(n, why) for n, why in skipped if n.lower().endswith(_OTHER_DATA)]
    path = write_batch_report(items, files, args.out, command=command, force=args.force,
                              skipped=tables)
    n_ok = sum(i.status in _CONVERGED for i in items)
    for item, f in zip(items, files):
        what = cli_words(item.result.summary()) if item.result is not None else item.error
        print(f"{item.status}: {one_line(os.path.basename(f))}: {one_line(what)}")
    tally = ", ".join(f"{n} {status}"
                      for status, n in collections.Counter(i.status for i in items).items())
    print(f"{n_ok}/{len(items)} converged ({tally}); report: {path}")
    return 0 if n_ok == len(items) else 1

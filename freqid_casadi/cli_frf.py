"""The ``freqid frf`` command: frequency response from periodic time records (layer L6).

Usage::

    freqid frf RECORDS.csv --period N [--fs HZ] [--skip-periods P] --out frf.csv [--force]

Reads a two-column ``u,y`` CSV (:func:`freqid_casadi.experiment.load_records_csv`),
estimates the frequency response at the excited DFT bins averaged over the periods
(:func:`freqid_casadi.experiment.frf_from_periodic`, SPEC §7) and writes

- ``frf.csv``: ``omega,real,imag`` (:func:`freqid_casadi.data.save_csv`), ready for
  ``freqid fit``; ``omega`` in rad/s with ``--fs``, else rad/sample;
- with two or more periods, the sidecar ``frf.stats.csv``:
  ``omega,bin,variance,coherence,weight`` (variance of the mean over periods, magnitude-
  squared coherence, and the fitting weight ``|G|^2 / variance`` normalised to mean 1).

Both files are written atomically (temporary file, then ``os.replace``). This module only
defines the parser (:func:`add_cli`) and the command (:func:`run_cli`); ``cli.py`` registers
them. Errors are raised as :class:`~freqid_casadi.errors.FreqidError` for the caller to
print as ``error: ...``.
"""

import argparse
import math
import os

from ._io import atomic_write_text
from ._outputs import check_out_file
from .data import save_csv
from .errors import OptionError
from .experiment import frf_from_periodic, load_records_csv

__all__ = ["add_cli", "run_cli", "stats_path", "NAME"]

#: Name of the command.
NAME = "frf"


def _period(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer >= 2, got {text!r}") from None
    if value < 2:
        raise argparse.ArgumentTypeError(f"must be an integer >= 2, got {value}")
    return value


def _count(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {value}")
    return value


def _fs(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number > 0 (Hz), got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0 (Hz), got {text!r}")
    return value


def add_cli(subparsers):
    """Add the ``frf`` subparser to ``subparsers`` (from ``add_subparsers``); return it."""
    p = subparsers.add_parser(
        NAME, help="frequency response from periodic (multisine) u,y records",
        description="Estimate the frequency response at the excited DFT bins of a periodic "
                    "experiment, averaged over the periods (SPEC §7), from a CSV with the "
                    "header 'u,y', and write omega,real,imag CSV for 'freqid fit'.")
    p.add_argument("records", metavar="RECORDS.csv", help="input/output samples, header u,y")
    p.add_argument("--period", type=_period, required=True, metavar="N",
                   help="samples per period of the excitation")
    p.add_argument("--fs", type=_fs, metavar="HZ",
                   help="sampling frequency in Hz (omega in rad/s); default: normalised "
                        "frequency, omega in rad/sample")
    p.add_argument("--skip-periods", type=_count, default=0, metavar="P",
                   help="leading periods to discard as transient (default 0)")
    p.add_argument("--out", required=True, metavar="FRF.csv",
                   help="output CSV (omega,real,imag); with >= 2 periods also "
                        "<stem>.stats.csv")
    p.add_argument("--force", action="store_true", help="overwrite existing output files")
    return p


def stats_path(out):
    """Path of the variance/coherence sidecar of ``out``: ``<stem>.stats.csv``."""
    stem, ext = os.path.splitext(os.fspath(out))
    return f"{stem}.stats.csv" if ext.lower() == ".csv" else f"{os.fspath(out)}.stats.csv"


def _check_target(path, force, records=None):
    """Output file checks (:func:`freqid_casadi._outputs.check_out_file`): never the input
    ``records``, an existing file only with ``force``, never a folder."""
    check_out_file(path, force, inputs=() if records is None else (records,))


def _stats_text(est):
    lines = ["omega,bin,variance,coherence,weight"]
    d = est.data
    for w, k, v, c, wt in zip(d.omega.tolist(), est.bins.tolist(), est.variance.tolist(),
                              est.coherence.tolist(), d.weights.tolist()):
        lines.append(f"{w!r},{int(k)},{v!r},{c!r},{wt!r}")
    return "\n".join(lines) + "\n"


def run_cli(args, command):
    """Run ``freqid frf`` for the parsed ``args``; return the exit code (0).

    Parameters
    ----------
    args : argparse.Namespace
        With ``records``, ``period``, ``fs`` (None), ``skip_periods`` (0), ``out`` and
        ``force`` (False).
    command : str
        The command line (unused in the CSV files, which have fixed headers).

    Returns
    -------
    int
        0.

    Raises
    ------
    FreqidError
        DataError for bad records (see :func:`~freqid_casadi.experiment.frf_from_periodic`),
        OptionError for an existing output without ``--force`` or a missing folder.
    """
    force = bool(getattr(args, "force", False))
    out = args.out
    _check_target(out, force, args.records)
    u, y = load_records_csv(args.records)
    name = os.path.splitext(os.path.basename(os.fspath(args.records)))[0]
    est = frf_from_periodic(u, y, args.period, fs=getattr(args, "fs", None),
                            skip_periods=getattr(args, "skip_periods", 0) or 0, name=name)
    sidecar = stats_path(out) if est.variance is not None else None
    if sidecar is not None:
        _check_target(sidecar, force, args.records)
    save_csv(est.data, out)
    if sidecar is not None:
        atomic_write_text(sidecar, _stats_text(est))
    unit = "rad/s" if est.fs is not None else "rad/sample"
    d = est.data
    print(f"{d.n_points} excited bins ({int(est.bins[0])}..{int(est.bins[-1])}), "
          f"omega {d.omega[0]:.4g} to {d.omega[-1]:.4g} {unit}, {est.n_periods} period(s) "
          f"averaged")
    print(f"frf: {os.path.abspath(out)}")
    if sidecar is not None:
        print(f"variance/coherence: {os.path.abspath(sidecar)}")
    else:
        print("one period: no variance or coherence estimate (record >= 2 periods)")
    return 0

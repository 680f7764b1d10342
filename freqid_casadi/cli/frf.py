"""The ``freqid frf`` command: frequency response from time records (layer L6).

Usage::

    freqid frf RECORDS.csv --period N [--fs HZ] [--skip-periods P] --out frf.csv [--force]
    freqid frf RECORDS --estimator h1|h2 --fs HZ [--nperseg N] [--noverlap N]
               [--window hann] [--min-coherence X] [--input CH --output CH] --out frf.csv
    freqid frf REC.mat --u NAME --y NAME [--reference NAME] [--band LO:HI] ... --out frf.csv
    freqid frf --u-file U.mat --y-file Y.mat [--u NAME] [--y NAME] [--fs HZ] ... --out frf.csv
    freqid frf REC.lvm --input CH --output CH [--lvm-segment K] ... --out frf.csv

Reads a two-column ``u,y`` CSV (:func:`freqid_casadi.experiment.load_records_csv`), a DAQ
export (:func:`freqid_casadi.experiment.load_daq_records`, channels chosen by ``--input``
and ``--output``) or a MATLAB file of time records
(:func:`freqid_casadi.experiment.load_records_mat`, variables or struct fields chosen by
``--u`` and ``--y``; ``--reference`` names the generated excitation, whose lines are the
excited ones), or the input and the output from two MATLAB files (``--u-file`` and
``--y-file``, as benchmarks publish ``uval`` and ``yval``: the only record of each file, or
the one ``--u``/``--y`` names; both of one length, and of one rate if both state one).
A LabVIEW measurement file (``.lvm``, :func:`freqid_casadi.experiment.lvm_segments`) of
several segments is read as one record, its segments joined end to end (each must hold the
chosen channels at one rate; a note says how many were joined and whether their time stamps
make one continuous acquisition), or one segment alone with ``--lvm-segment K``. It then
estimates the frequency response at the excited DFT bins averaged over
the periods (:func:`freqid_casadi.experiment.frf_from_periodic`, SPEC §7) or by Welch H1/H2
(:func:`freqid_casadi.experiment.frf_from_records`), keeps the frequencies in ``--band``
(Hz with a sampling rate) and writes

- ``frf.csv``: ``omega,real,imag`` (:func:`freqid_casadi.io.loaders.save_csv`), ready for
  ``freqid fit``; ``omega`` in rad/s with ``--fs``, else rad/sample;
- with two or more periods, the sidecar ``frf.stats.csv``:
  ``omega,bin,variance,coherence,weight`` (variance of the mean over periods, magnitude-
  squared coherence, and the fitting weight ``|G|^2 / variance`` normalised to mean 1;
  ``bin`` is the DFT bin of the period or of the Welch segment).

Both files are written atomically (temporary file, then ``os.replace``). This module only
defines the parser (:func:`add_cli`) and the command (:func:`run_cli`);
:data:`freqid_casadi.cli.app.COMMANDS` registers them. Errors are raised as
:class:`~freqid_casadi.errors.FreqidError` for the caller to print as ``error: ...``.
"""

import math
import os

import numpy as np

from ..report.outputs import check_out_file

from .._textio import atomic_write_text
from ..errors import DataError, OptionError
from ..experiment import (ESTIMATORS, excitation_gaps, frf_from_periodic, frf_from_realisations,
                         frf_from_records, load_daq_records, load_records_mat,
                         load_records_table, lvm_segments)
from .common import _ASCII_FLOAT, _ASCII_INT, _ascii, _checked   # the CLI's own type helpers
from .common import parse_band_text
from ..io.loaders import is_mat, read_regular_file, save_csv

__all__ = ["add_cli", "run_cli", "read_records", "read_excitation", "stats_path", "NAME"]

#: Name of the command.
NAME = "frf"


_INT = _ascii(_ASCII_INT, int)          # ASCII decimal numbers only, as the other commands
_FLOAT = _ascii(_ASCII_FLOAT, float)    # ("1_0" and non-ASCII digits are refused)


def _period(text):
    return _checked(text, _INT, lambda v: v >= 2, "must be an integer >= 2",
                    lambda v: f"must be an integer >= 2, got {v}")


def _count(text):
    return _checked(text, _INT, lambda v: v >= 0, "must be an integer >= 0",
                    lambda v: f"must be an integer >= 0, got {v}")


def _fs(text):
    return _checked(text, _FLOAT, lambda v: math.isfinite(v) and v > 0,
                    "must be a number > 0 (Hz)",
                    lambda v: f"must be a finite number > 0 (Hz), got {text!r}")


def _segment(text):
    return _checked(text, _INT, lambda v: v >= 1, "must be an integer >= 1",
                    lambda v: f"must be an integer >= 1 (1 = the first segment), got {v}")


def _fraction(text):
    return _checked(text, _FLOAT, lambda v: 0 <= v < 1, "must be a number in [0, 1)",
                    lambda v: f"must be a number in [0, 1), got {text!r}")


def _decibels(text):
    return _checked(text, _FLOAT, lambda v: math.isfinite(v) and v > 0,
                    "must be a number of decibels > 0",
                    lambda v: f"must be a finite number of decibels > 0, got {text!r}")


def add_cli(subparsers):
    """Add the ``frf`` subparser to ``subparsers`` (from ``add_subparsers``); return it.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The result of ``ArgumentParser.add_subparsers``.
    """
    p = subparsers.add_parser(
        NAME, help="frequency response from u,y records (periodic, chirp, random)",
        description="Estimate the frequency response from input/output records and write "
                    "omega,real,imag CSV for 'freqid fit': averaged over the periods of a "
                    "periodic excitation (--period, SPEC §7), or Welch H1/H2 for any "
                    "excitation (--estimator h1|h2). RECORDS is a CSV with the header 'u,y' "
                    "or a DAQ export ('Header Size: N' first line, .xz accepted; choose "
                    "--input and --output channels), or a MATLAB .mat file of time records "
                    "(choose --u and --y variables), or a LabVIEW measurement file (.lvm; "
                    "its segments joined, or --lvm-segment K); or, instead of RECORDS, the "
                    "input and the output in two .mat files: --u-file U.mat --y-file Y.mat.")
    p.add_argument("records", metavar="RECORDS", nargs="?",
                   help="u,y CSV or a table with named columns, a DAQ export, a .mat file or "
                        "a LabVIEW .lvm file (omit with --u-file/--y-file)")
    p.add_argument("--estimator", choices=("periodic",) + ESTIMATORS,
                   help="periodic (needs --period), h1 (noise on the output) or h2 (noise "
                        "on the input); default periodic with --period, else h1")
    p.add_argument("--period", type=_period, metavar="N",
                   help="samples per period of a periodic excitation")
    p.add_argument("--fs", type=_fs, metavar="HZ",
                   help="sampling frequency in Hz (omega in rad/s; required for h1/h2 "
                        "unless the DAQ header gives it); periodic default: rad/sample")
    p.add_argument("--skip-periods", type=_count, default=0, metavar="P",
                   help="leading periods to discard as transient (default 0)")
    p.add_argument("--nperseg", type=_period, metavar="N",
                   help="h1/h2: samples per Welch segment (default: largest power of 2 "
                        "<= N/8)")
    p.add_argument("--noverlap", type=_count, metavar="N",
                   help="h1/h2: overlap of the segments (default nperseg/2)")
    p.add_argument("--window", default="hann", help="h1/h2: scipy window (default hann)")
    p.add_argument("--min-coherence", type=_fraction, metavar="X",
                   help="h1/h2: keep only frequencies with coherence >= X (e.g. 0.9)")
    p.add_argument("--input", metavar="CHANNEL",
                   help="input channel of a DAQ export, or input column of a table whose "
                        "header names its columns (Force, CH1, ...)")
    p.add_argument("--output", metavar="CHANNEL",
                   help="output channel of a DAQ export, or output column of a table")
    p.add_argument("--u", metavar="NAME",
                   help=".mat file: the input record's variable (e.g. u or meas.force)")
    p.add_argument("--y", metavar="NAME",
                   help=".mat file: the output record's variable (e.g. y or meas.acc)")
    p.add_argument("--u-file", metavar="U.mat",
                   help="a .mat file holding the input record, with --y-file instead of "
                        "RECORDS (--u names the variable if the file holds several)")
    p.add_argument("--y-file", metavar="Y.mat",
                   help="a .mat file holding the output record, with --u-file")
    p.add_argument("--lvm-segment", type=_segment, metavar="K",
                   help="LabVIEW .lvm file of several segments: read segment K alone (1 = "
                        "the first); default: all of them joined end to end")
    p.add_argument("--reference", metavar="NAME",
                   help=".mat variable or DAQ channel of the generated excitation: only the "
                        "lines it excites are kept (a measured input holds noise at the "
                        "others)")
    p.add_argument("--threshold", type=_decibels, metavar="DB",
                   help="a line counts as excited when its power (of the input, or of "
                        "--reference) is within DB decibels of the strongest line "
                        "(default 20)")
    p.add_argument("--fill-grid", action="store_true",
                   help="periodic: keep every line of the excitation's grid (odd bins, "
                        "every k-th bin) between the first and the last excited line, also "
                        "where the measured input dips below the threshold")
    p.add_argument("--band", type=parse_band_text, metavar="LO:HI",
                   help="keep only the frequencies LO <= f <= HI (Hz with a sampling rate, "
                        "else rad/sample)")
    p.add_argument("--out", required=True, metavar="FRF.csv",
                   help="output CSV (omega,real,imag); with a variance also "
                        "<stem>.stats.csv")
    p.add_argument("--force", action="store_true", help="overwrite existing output files")
    return p


def stats_path(out):
    """Path of the variance/coherence sidecar of ``out``: ``<stem>.stats.csv``.

    Parameters
    ----------
    out : str or path-like
        The CSV file the FRF is written to.
    """
    stem, ext = os.path.splitext(os.fspath(out))
    return f"{stem}.stats.csv" if ext.lower() == ".csv" else f"{os.fspath(out)}.stats.csv"


def _check_target(path, force, inputs=()):
    """Output file checks (:func:`freqid_casadi.report.outputs.check_out_file`): never one of
    the ``inputs`` (the records files), an existing file only with ``force``, never a
    folder."""
    check_out_file(path, force, inputs=inputs)


def _inputs(args):
    """The files the command reads: RECORDS, or the --u-file and the --y-file."""
    names = ("records", "u_file", "y_file")
    return tuple(p for p in (getattr(args, n, None) for n in names) if p is not None)


def _two_files(args):
    """True when the input and the output come in two files (``--u-file``, ``--y-file``),
    False for one RECORDS file; OptionError for neither, one of the two, or both
    spellings."""
    u_file, y_file = getattr(args, "u_file", None), getattr(args, "y_file", None)
    records = getattr(args, "records", None)
    if u_file is None and y_file is None:
        if records is None:
            raise OptionError("no records given: pass RECORDS (a file holding the input and "
                              "the output), or the two files: --u-file U.mat --y-file Y.mat")
        return False
    if u_file is None or y_file is None:
        given, missing = ("--u-file", "--y-file") if y_file is None else ("--y-file",
                                                                          "--u-file")
        raise OptionError(f"{given} needs {missing}: pass the input's file and the output's "
                          "file, e.g. freqid frf --u-file U.mat --y-file Y.mat ...")
    if records is not None:
        raise OptionError(f"RECORDS {records!r} and --u-file/--y-file both give the records: "
                          "pass one file holding both as RECORDS, or the two files with "
                          "--u-file and --y-file (without RECORDS)")
    return True


def _file_record(path, opt, args):
    """``(samples, name, DaqRecords)`` of the record that ``--u`` (``opt`` "u") or ``--y``
    names in ``--u-file``/``--y-file`` ``path``: the file's only record by default."""
    alias = "input" if opt == "u" else "output"
    if not _is_mat(path):
        raise OptionError(f"--{opt}-file {path!r} is not a MATLAB .mat file: --u-file and "
                          "--y-file read .mat files; a text table holds the input and the "
                          "output together: pass it as RECORDS (with --input/--output)")
    rec = load_records_mat(path, min_records=1)
    names = ", ".join(rec.channels)
    name = getattr(args, opt, None) or getattr(args, alias, None)
    # one matrix whose rows (or columns) are all the file's records: its realisations
    whole = [k for k in rec.matrices if (r := rec.realisations(k)) is not None
             and r.shape[0] == len(rec.channels)]
    if name is None:
        if len(rec.channels) == 1:
            name = next(iter(rec.channels))
        elif len(whole) == 1:
            name = whole[0]
        elif opt in rec.channels:
            name = opt
        else:
            raise OptionError(f"--{opt}-file {path!r} holds several records ({names}): "
                              f"choose the {alias} with --{opt} NAME")
    found = _record(rec, name)
    if found is None:
        raise OptionError(_nd_hint(rec, name, opt) or
                          f"--{opt} {name!r} is not a time record of --{opt}-file {path!r}; "
                          f"its records are {names}")
    return found, name, rec


def _two_file_records(args):
    """Input, output, sampling rate (or None) and reference (or None) of ``--u-file`` and
    ``--y-file``: records of one length, files that state no contradicting rates."""
    u, u_name, u_rec = _file_record(args.u_file, "u", args)
    y, y_name, y_rec = _file_record(args.y_file, "y", args)
    if u.ndim == y.ndim and u.shape != y.shape:    # (run_cli refuses other layouts)
        raise DataError(f"the input {u_name!r} of --u-file {args.u_file!r} holds "
                        f"{_samples(u)}, the output {y_name!r} of --y-file {args.y_file!r} "
                        f"holds {_samples(y)}: the two records must cover the same samples; "
                        "choose records of one experiment (--u NAME, --y NAME) or cut the "
                        "longer one")
    if (u_rec.fs is not None and y_rec.fs is not None
            and not math.isclose(u_rec.fs, y_rec.fs, rel_tol=1e-9)):
        raise DataError(f"--u-file {args.u_file!r} states the sampling rate {u_rec.fs:g} Hz, "
                        f"--y-file {args.y_file!r} {y_rec.fs:g} Hz: the input and the output "
                        "must be sampled together; check that the files belong to one "
                        "experiment")
    fs = u_rec.fs if u_rec.fs is not None else y_rec.fs
    _same_rate(args, fs)
    ref = getattr(args, "reference", None)
    if ref is None:
        return u, y, fs, None
    for rec in (u_rec, y_rec):
        found = _record(rec, ref)
        if found is not None:
            return u, y, fs, found
    raise OptionError(f"--reference {ref!r} is not a time record of --u-file or --y-file; "
                      f"their records are {', '.join(list(u_rec.channels) + list(y_rec.channels))}")


def _is_daq(path):
    if os.fspath(path).lower().endswith(".xz"):
        return True
    _, payload = read_regular_file(path, "records file")
    return payload.lstrip(b"\xef\xbb\xbf").startswith(b"Header Size")


def _is_mat(path):
    """A file of named arrays: MATLAB or Octave (:func:`is_mat`), or a NumPy archive."""
    return is_mat(path) or os.fspath(path).lower().endswith(".npz")


def _is_lvm(path):
    """True for a LabVIEW measurement file (first line ``LabVIEW Measurement``)."""
    if _is_mat(path) or os.fspath(path).lower().endswith(".xz"):
        return False
    _, payload = read_regular_file(path, "records file")
    return payload.lstrip(b"\xef\xbb\xbf").startswith(b"LabVIEW Measurement")


def _check_segment(args, two_files):
    """OptionError for ``--lvm-segment`` with records other than a LabVIEW file."""
    if getattr(args, "lvm_segment", None) is None:
        return
    if two_files or not _is_lvm(args.records):
        what = "--u-file/--y-file" if two_files else f"RECORDS {args.records!r}"
        raise OptionError(f"--lvm-segment chooses a segment of a LabVIEW measurement file "
                          f"(.lvm, first line 'LabVIEW Measurement'); {what} is not one: "
                          "drop --lvm-segment")


def _mat_records(args):
    """Input, output, sampling rate (or None) and reference (or None) of a ``.mat`` file."""
    rec = load_records_mat(args.records)
    names = ", ".join(rec.channels)
    chosen = []
    for opt, alias, default in (("u", "input", "u"), ("y", "output", "y")):
        name = getattr(args, opt, None) or getattr(args, alias, None)
        found = _record(rec, name if name is not None else default)
        if found is None:
            what = (f"is required: name the {alias} record's variable" if name is None
                    else f"{name!r} is not a time record of the file")
            raise OptionError(_nd_hint(rec, name or default, opt) or
                              f"--{opt} {what}; the records are {names} (e.g. freqid frf "
                              f"FILE --u NAME --y NAME)")
        chosen.append(found)
    ref = getattr(args, "reference", None)
    _same_rate(args, rec.fs)
    if ref is None:
        return chosen[0], chosen[1], rec.fs, None
    found = _record(rec, ref)
    if found is None and chosen[0].ndim == 2:
        found = _period_reference(rec, ref, chosen[0].shape[0])
    if found is None and chosen[0].ndim == 1 and ref in rec.others:
        found = rec.others[ref]          # one period, repeated (else the estimate says)
    if found is None:
        raise OptionError(_nd_hint(rec, ref, "reference") or
                          f"--reference {ref!r} is not a time record of the file (a "
                          "reference is as long as the records, or one period); the "
                          f"records are {names}")
    return chosen[0], chosen[1], rec.fs, found


def _period_reference(rec, name, count):
    """The rows of the matrix ``name`` of the .mat records ``rec`` when it holds ``count``
    records (rows or columns) of another length than the records (a generator's one
    period per realisation, repeated by :func:`~freqid_casadi.experiment.
    frf_from_realisations`); else None."""
    a = rec.matrices.get(name)
    if a is None or a.ndim != 2 or count not in a.shape:
        return None
    return np.asarray(a if a.shape[0] == count else a.T, float)


def _record(rec, name):
    """The record ``name`` of the .mat records ``rec``: a vector, or a matrix's
    realisations as an (R, N) array (:meth:`~freqid_casadi.experiment.DaqRecords.
    realisations`); None when there is no such record."""
    if name is None:
        return None
    return rec.channels[name] if name in rec.channels else rec.realisations(name)


def _nd_hint(rec, name, opt):
    """The message for ``--{opt} NAME`` naming an array of three or more dimensions (or a
    matrix of another length than the records) of the .mat records ``rec``, else None."""
    a = rec.matrices.get(name)
    if a is None:
        return None
    shape = " x ".join(map(str, a.shape))
    return (f"--{opt} {name!r} is a {shape} array, not a record or a matrix of "
            "realisations of the records' length: freqid frf reads a record as a vector, "
            "realisations as the rows (or columns) of a matrix; for a realisation x period x "
            "sample array, in Python: experiment.frf_from_realisations(u.reshape(R, -1), "
            "y.reshape(R, -1), period, fs=...)")


def _samples(x):
    """``"8192 samples"`` or ``"3 realisations of 8192 samples"``."""
    return (f"{x.size} samples" if x.ndim == 1 else
            f"{x.shape[0]} realisations of {x.shape[1]} samples")


def _check_realisations(u, y, ref, estimator):
    """OptionError/DataError for realisations (an R x N record) the estimate cannot take:
    another count in the output, a one-record reference, or a Welch estimator."""
    if u.ndim == 1 and y.ndim == 1:
        return
    if u.ndim != y.ndim:
        one, many, x = ("input", "output", y) if u.ndim == 1 else ("output", "input", u)
        flag = "--y" if many == "output" else "--u"
        raise OptionError(f"the {one} is one record and the {many} a matrix of {x.shape[0]} "
                          f"records (its rows or columns): choose one of them, e.g. {flag} "
                          "'NAME(2,:)'; realisations are averaged when the input and the "
                          "output are both matrices of them")
    if u.shape != y.shape:
        raise DataError(f"the input holds {_samples(u)} and the output {_samples(y)}: "
                        "pass the input and the output of the same realisations")
    if estimator != "periodic":
        raise OptionError(f"the records hold {u.shape[0]} realisations (a matrix's rows or "
                          "columns): they are averaged for a periodic excitation (--period "
                          f"N); for --estimator {estimator} choose one, e.g. --u 'NAME(2,:)' "
                          "--y 'NAME(2,:)'")
    if ref is not None and np.shape(ref)[0] != u.shape[0]:
        raise DataError(f"--reference holds {_samples(np.asarray(ref))} for {_samples(u)} "
                        "of the input: pass the generated excitation of every realisation")


def read_excitation(args):
    """Input, output, the sampling rate the file states (or None) and the reference
    record (``--reference``, or None) for ``args``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed ``freqid frf`` arguments.

    Raises
    ------
    DataError
        A bad records file.
    OptionError
        Channels or variables that are not in the file, options that do not apply.
    """
    if _two_files(args):
        return _two_file_records(args)
    if _is_mat(args.records):
        return _mat_records(args)
    for opt in ("u", "y"):
        if getattr(args, opt, None):
            raise OptionError(f"--{opt} names a variable of a .mat file; a u,y CSV has its "
                              "input in column u and its output in column y, a DAQ export "
                              "takes --input/--output")
    ref = getattr(args, "reference", None)
    if ref is not None and not _is_daq(args.records):
        raise OptionError("--reference names a .mat variable or a DAQ channel; a u,y CSV "
                          "has no reference column (use --band, or --period for a periodic "
                          "excitation, whose excited lines come from u)")
    u, y, fs = read_records(args)
    if ref is None:
        return u, y, fs, None
    rec = load_daq_records(args.records)
    if ref not in rec.channels:
        raise OptionError(f"--reference {ref!r} is not a channel: choose one of "
                          f"{', '.join(rec.channels)}")
    return u, y, fs, rec.channels[ref]


def read_records(args):
    """Input, output and the sampling rate the file states (or None) for ``args``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed ``freqid frf`` arguments (records path, ``--input``/``--output``, or
        ``--u-file``/``--y-file``).

    Raises
    ------
    DataError
        A bad records file.
    OptionError
        A DAQ export without valid ``--input``/``--output`` channels, or ``--fs`` that
        contradicts its header.
    """
    if _two_files(args):
        return _two_file_records(args)[:3]
    if _is_mat(args.records):
        return _mat_records(args)[:3]
    if not _is_daq(args.records):
        u, y, fs = load_records_table(args.records, getattr(args, "input", None),
                                      getattr(args, "output", None),
                                      segment=getattr(args, "lvm_segment", None))
        _same_rate(args, fs, rel_tol=1e-3, where=" (from its time or Fs column)")
        return u, y, fs
    rec = load_daq_records(args.records)
    names = ", ".join(rec.channels)
    for opt in ("input", "output"):
        ch = getattr(args, opt, None)
        if ch not in rec.channels:
            what = "is required" if ch is None else f"{ch!r} is not a channel"
            raise OptionError(f"--{opt} {what} for a DAQ export: choose one of {names}")
    _same_rate(args, rec.fs)
    return rec.channels[args.input], rec.channels[args.output], rec.fs


def _same_rate(args, fs, rel_tol=0.0, where=""):
    """OptionError when ``--fs`` contradicts the rate ``fs`` (Hz) the file states (None:
    it states none); ``rel_tol`` 0: they must be equal (a DAQ header, a .mat scalar), a
    rate from time stamps within it."""
    given = getattr(args, "fs", None)
    if given is not None and fs is not None and not math.isclose(given, fs, rel_tol=rel_tol):
        raise OptionError(f"--fs {given:g} contradicts the file's sampling rate {fs:g} Hz"
                          f"{where}; drop --fs")


_STATS_HEADER = "omega,bin,variance,coherence,weight"


def _own_sidecar(path):
    """True if ``path`` is a regular file whose first line is the sidecar's header (one
    that ``freqid frf`` wrote)."""
    try:
        with open(path, "rb") as fh:
            first = fh.read(len(_STATS_HEADER) + 2)
    except OSError:
        return False
    return os.path.isfile(path) and first.splitlines()[:1] == [_STATS_HEADER.encode()]


def _check_sidecar(sidecar, force, inputs):
    """The sidecar is never named by the user: with ``force`` it replaces only a sidecar
    that ``freqid frf`` wrote (a file of the user's with that name is kept)."""
    _check_target(sidecar, force, inputs)
    if os.path.lexists(sidecar) and not _own_sidecar(sidecar):
        raise OptionError(f"refusing to replace {sidecar!r} (the variance/coherence file "
                          f"written beside --out): it was not written by freqid frf; move "
                          "it or choose another --out")


def _stats_text(est):
    lines = [_STATS_HEADER]
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
        With ``records`` (or ``u_file`` and ``y_file``), ``out`` and optionally
        ``estimator``, ``period``, ``fs``, ``skip_periods``, ``nperseg``, ``noverlap``,
        ``window``, ``min_coherence``, ``input``, ``output``, ``u``, ``y``, ``reference``,
        ``lvm_segment``, ``band`` and ``force`` (absent ones take their defaults).
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
    two_files = _two_files(args)
    _check_segment(args, two_files)
    inputs = _inputs(args)
    _check_target(out, force, inputs)
    estimator = getattr(args, "estimator", None)
    period = getattr(args, "period", None)
    if estimator is None:
        estimator = "periodic" if period is not None else "h1"
    if estimator == "periodic" and period is None:
        raise OptionError("--estimator periodic needs --period N (samples per period); for "
                          "a chirp or random test use --estimator h1")
    if estimator != "periodic" and period is not None:
        raise OptionError(f"--period is for a periodic excitation, not --estimator {estimator}")
    if estimator != "periodic" and getattr(args, "fill_grid", False):
        raise OptionError("--fill-grid is for --estimator periodic (the lines of a "
                          "multisine's grid); a Welch estimate keeps every frequency")
    u, y, fs_file, ref = read_excitation(args)
    _check_realisations(u, y, ref, estimator)
    if not two_files and _is_lvm(args.records):
        _segments_note(args.records, getattr(args, "lvm_segment", None))
    fs = getattr(args, "fs", None) or fs_file
    name = os.path.splitext(os.path.basename(os.fspath(args.y_file if two_files
                                                      else args.records)))[0]
    threshold = 10.0 ** (-(getattr(args, "threshold", None) or DEFAULT_THRESHOLD_DB) / 10)
    filled = 0
    if estimator == "periodic":
        skip = getattr(args, "skip_periods", 0) or 0
        try:
            est = (frf_from_realisations(u, y, period, fs=fs, skip_periods=skip, name=name,
                                         references=ref, threshold=threshold)
                   if u.ndim == 2 else
                   frf_from_periodic(u, y, period, fs=fs, skip_periods=skip, name=name,
                                     reference=ref, threshold=threshold))
        except DataError as exc:        # the Python-only option, in this command's words
            raise DataError(str(exc).replace(
                "give the right period, or pass allow_partial=True to drop the trailing "
                "partial period", "or give the right period")) from None
        est, filled = _filled(est, args, u, y, period, skip, ref)
    else:
        est = frf_from_records(u, y, fs=fs, estimator=estimator,
                               nperseg=getattr(args, "nperseg", None),
                               noverlap=getattr(args, "noverlap", None),
                               window=getattr(args, "window", "hann"),
                               min_coherence=getattr(args, "min_coherence", None), name=name,
                               reference=ref, threshold=threshold)
    est = _in_band(est, getattr(args, "band", None))
    sidecar = stats_path(out) if est.variance is not None else None
    if sidecar is not None:
        _check_sidecar(sidecar, force, inputs)
    stale = stats_path(out) if sidecar is None and _own_sidecar(stats_path(out)) else None
    if stale is not None:      # an earlier run's statistics would not belong to this FRF
        _check_sidecar(stale, force, inputs)
    save_csv(est.data, out)
    if sidecar is not None:
        atomic_write_text(sidecar, _stats_text(est))
    if stale is not None:
        os.remove(stale)
    _summary(est, out, sidecar)
    if filled:
        print(f"--fill-grid: kept {filled} line(s) of the excitation's grid below the "
              "threshold")
    elif estimator == "periodic" and u.ndim == 1 and ref is None:
        _gaps_note(u, period, est.bins, skip, getattr(args, "threshold", None))
    return 0


def _segments_note(path, chosen):
    """Say on stdout which segments of a LabVIEW file of several were read, and whether
    their time stamps make them one continuous acquisition."""
    segs = lvm_segments(path)
    if len(segs) < 2:
        return
    if chosen is not None:
        s = segs[chosen - 1]
        print(f"LabVIEW file: segment {chosen} of {len(segs)} read (line {s.line}, "
              f"{s.samples} samples)")
        return
    sizes = sorted({s.samples for s in segs})
    each = (f"{sizes[0]} samples each" if len(sizes) == 1 else
            f"{min(sizes)} to {max(sizes)} samples")
    print(f"LabVIEW file: {len(segs)} segments joined end to end ({each}, "
          f"{sum(s.samples for s in segs)} in all); --lvm-segment K reads one alone")
    if any(s.start is None or s.fs is None for s in segs):
        print("  their headers give no start times: read as one continuous acquisition")
        return
    for a, b in zip(segs, segs[1:]):
        gap = b.start - (a.start + a.samples / a.fs)
        if abs(gap) > 0.5 / a.fs + 2e-6:
            where = "after" if gap > 0 else "before"
            print(f"warning: segment {b.number} starts {abs(gap):.6g} s {where} segment "
                  f"{a.number} ends (Date/Time): separate acquisitions, joined as one "
                  "record; a periodic estimate needs whole periods in each segment, and "
                  "Welch segments across a join mix the two; pass --lvm-segment K to read "
                  "one alone")
            return
    print("  their time stamps make one continuous acquisition (each segment starts "
          "where the one before ends)")


def _in_band(est, band):
    """``est`` at the frequencies in ``band`` (Hz with a sampling rate, else rad/sample),
    the points dropped said on stdout."""
    if band is None:
        return est
    f = est.data.omega / (2 * math.pi) if est.fs is not None else est.data.omega
    unit = "Hz" if est.fs is not None else "rad/sample"
    keep = (f >= band[0]) & (f <= band[1])
    if not keep.any():
        raise OptionError(f"--band {band[0]:g}:{band[1]:g} {unit} holds none of the "
                          f"estimate's frequencies ({f[0]:.4g} to {f[-1]:.4g} {unit}); widen it")
    if not keep.all():
        print(f"band {band[0]:g}:{band[1]:g} {unit}: kept {int(keep.sum())} of {keep.size} "
              f"frequencies")
    return est.subset(keep)


#: ``--threshold``'s default: a line within 20 dB of the strongest counts as excited.
DEFAULT_THRESHOLD_DB = 20.0


def _gaps_note(u, period, bins, skip, given):
    """Which lines of the excitation's grid inside the band fell below the threshold."""
    step, gaps = excitation_gaps(u, period, bins, skip_periods=skip)
    if not gaps:
        return
    grid = "odd bins" if step == 2 and bins[0] % 2 else f"every {step}th bin"
    shown = ", ".join(f"{k} ({v:.3g} dB)" for k, v in gaps[:8])
    more = f" and {len(gaps) - 8} more" if len(gaps) > 8 else ""
    fix = ("pass --fill-grid to keep them" if all(math.isfinite(v) for _, v in gaps)
           else "they hold no input at all")
    print(f"note: {len(gaps)} line(s) of the excitation's grid ({grid}) inside the band "
          f"are below the threshold ({-(given or DEFAULT_THRESHOLD_DB):g} dB of the "
          f"strongest line) and were left out: {'bins' if len(gaps) > 1 else 'bin'} "
          f"{shown}{more}. A measured input (a "
          "force, a torque) dips at a resonance of the structure it drives; an odd-random "
          f"multisine leaves lines out on purpose. If they were excited, {fix}.")


def _filled(est, args, u, y, period, skip, ref):
    """``--fill-grid``: the estimate at every line of its excitation's grid, and how many
    lines that added (the estimate as it was and 0 without the option)."""
    if not getattr(args, "fill_grid", False):
        return est, 0
    if u.ndim != 1 or ref is not None:
        raise OptionError("--fill-grid is for a single record without --reference (the "
                          "reference's lines are the excited ones)")
    step, gaps = excitation_gaps(u, period, est.bins, skip_periods=skip)
    if not gaps:
        return est, 0
    bins = np.arange(est.bins[0], est.bins[-1] + 1, step)
    return frf_from_periodic(u, y, period, fs=est.fs, skip_periods=skip, bins=bins,
                             name=est.data.name), len(gaps)


#: Median coherence of a Welch estimate below which ``freqid frf`` warns.
LOW_COHERENCE = 0.3


def _distortion_line(est):
    """The realisations' variance against their noise's: the nonlinear distortions."""
    g2 = np.abs(est.data.response) ** 2
    total = float(np.sqrt(np.median(est.variance / g2)))
    noise = float(np.sqrt(np.median(est.noise_variance / g2)))
    ratio = total / noise if noise > 0 else math.inf
    verdict = ("the spread over the realisations is the noise: no nonlinear distortion "
               "shows" if ratio < 1.5 else
               "the realisations differ by more than their noise: nonlinear distortions "
               "(the variance in frf.stats.csv holds them, so a fit weighted by it treats "
               "them as noise)")
    return (f"relative standard deviation of the estimate (median over the bins): {total:.3g} "
            f"from the realisations, {noise:.3g} from the periods' noise ({ratio:.2g}x): "
            f"{verdict}")


def _summary(est, out, sidecar):
    unit = "rad/s" if est.fs is not None else "rad/sample"
    d = est.data
    if est.n_averages is not None:
        c, median = est.coherence, float(np.median(est.coherence))
        band = (f"{d.omega[0] / 2 / math.pi:.4g} to {d.omega[-1] / 2 / math.pi:.4g} Hz"
                if est.fs is not None else f"omega {d.omega[0]:.4g} to {d.omega[-1]:.4g} {unit}")
        print(f"{d.n_points} frequencies, {band} ({est.estimator.upper()}, {est.n_averages} "
              f"segments of {est.nperseg} samples); coherence min {c.min():.3f}, median "
              f"{median:.3f}")
        if median < LOW_COHERENCE:
            print(f"warning: the median coherence {median:.2g} is low: most of "
                  "the output is not explained by the input (noise, a nonlinearity, or an "
                  "excitation that few segments hold: an impact or a step, whose Welch "
                  "average is mostly silence); for a transient input pass --window boxcar "
                  "with --nperseg the length of one event, and check the input's spectrum "
                  "covers the band (--min-coherence drops the worst bins)")
    else:
        each = (f"{est.n_realisations} realisations of {est.n_periods} period(s) each"
                if est.n_realisations else f"{est.n_periods} period(s)")
        print(f"{d.n_points} excited bins ({int(est.bins[0])}..{int(est.bins[-1])}), "
              f"omega {d.omega[0]:.4g} to {d.omega[-1]:.4g} {unit}, {each} averaged")
        if est.noise_variance is not None:
            print(_distortion_line(est))
        elif est.n_realisations and est.variance is not None:
            print("one period each: the spread over the realisations holds the noise and "
                  "the nonlinear distortions together (two or more periods each tell them "
                  "apart)")
    if est.fs is None:
        print("no --fs: the omega column is in rad/sample, so a fit of it gives the delay in "
              "samples, not seconds (pass --fs HZ for rad/s)")
    print(f"frf: {os.path.abspath(out)}")
    if sidecar is not None:
        print(f"variance/coherence: {os.path.abspath(sidecar)}")
    else:
        print("one period: no variance or coherence estimate (record >= 2 periods)")

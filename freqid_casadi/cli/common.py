"""What several ``freqid`` commands share (layer 10): argument types, option groups, data
files, output lines and errors.

The argument types (``_positive_int``, ``_positive_float``, the ASCII-only number checks
``_ascii``/``_checked``) and the option groups of a fit (``_add_choices`` of
``_CHOICE_OPTIONS``, ``_common``, ``_add_model_arguments``, ``_add_input``) are the CLI's own
helpers, used by the command modules of this package only.
:func:`add_data_options` adds ``--freq-unit hz|rad/s``, ``--columns LIST`` and ``--band LO:HI``
to a parser;
:func:`load_data` loads a file with them (:func:`freqid_casadi.io.loaders.load`) and prints the
reader's notes (e.g. rows dropped at zero frequency) as ``note: ...`` lines on stderr
instead of Python warning text.
"""

import argparse
import contextlib
import dataclasses
import math
import os
import re
import sys
import warnings
from functools import partial

import numpy as np

from ..core.model import BASES, MAX_ORIGIN_ORDER, ZEROS
from ..fitting.fit import GAIN_SIGNS, METHODS, OBJECTIVES, STARTS
from ..fitting.verdict import ROUNDING_RMS
from ..io import NUMBER, decode_text, parse_columns, read_regular_file
from ..report.formatting import number
from ..core.data import FrequencyData
from ..io.loaders import DataWarning, load, refuse_options
from ..errors import DataError, OptionError
from ..options import LoopOptions, solver_options

__all__ = ["add_data_options", "parse_band_text", "load_data", "load_options", "refuse_flags",
           "notes_to_stderr", "grouped_notes", "with_weights", "error_line", "os_exit",
           "method_option", "print_continue_hint", "loop_option", "in_cli_words"]


def _columns(text):
    try:
        parse_columns(text)
    except OptionError as exc:
        raise argparse.ArgumentTypeError(str(exc).replace("columns", "", 1).lstrip(": "))
    return text


def parse_band_text(text):
    """``(lo, hi)`` from ``LO:HI`` (the ``--band`` option), e.g. ``65:1000``.

    Parameters
    ----------
    text : str

    Returns
    -------
    tuple of float

    Raises
    ------
    argparse.ArgumentTypeError
        Not two ASCII numbers ``0 <= LO < HI`` separated by a colon.
    """
    lo, sep, hi = str(text).partition(":")
    if not sep or not NUMBER.fullmatch(lo.strip()) or not NUMBER.fullmatch(hi.strip()):
        raise argparse.ArgumentTypeError(f"must be LO:HI in the file's frequency unit, e.g. "
                                         f"65:1000, got {text!r}")
    band = float(lo), float(hi)
    if not (np.isfinite(band).all() and 0 <= band[0] < band[1]):
        raise argparse.ArgumentTypeError(f"must be LO:HI with 0 <= LO < HI (finite), got "
                                         f"{text!r}")
    return band


def add_data_options(parser, records=False, weights=None):
    """Add ``--freq-unit``, ``--columns`` and ``--band`` to ``parser``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The sub-command's parser; returned for chaining.
    records : bool
        Also add ``--record K`` (UFF files with several records), ``--parameter S21``
        (Touchstone files) and ``--weights STATS.csv``, for commands that read one file.
    weights : bool, optional
        Whether to add ``--weights`` (default: as ``records``).
    """
    parser.add_argument(
        "--freq-unit", choices=("hz", "rad/s"), type=str.lower, metavar="hz|rad/s",
        help="unit of the frequency column when the file does not say it (a headerless "
             "file, a header 'f' or 'freq')")
    parser.add_argument(
        "--columns", type=_columns, metavar="LIST",
        help="names of the file's columns, e.g. 'f,re,im' or 'freq_hz,mag_db,phase_deg' "
             "(omega/w rad/s, freq_hz Hz, f with --freq-unit; re,im; mag or mag_db with "
             "phase_deg or phase_rad; complex; skip)")
    parser.add_argument(
        "--band", type=parse_band_text, metavar="LO:HI",
        help="keep only the frequencies LO <= f <= HI, in the file's frequency unit (Hz for "
             "'Frequency (Hz)' or a unit line 'Hz', rad/s for omega, GHz/MHz/... for "
             "Touchstone); a note says how many points were dropped")
    if records:
        parser.add_argument(
            "--record", type=_record, metavar="K",
            help="UFF file (.uff/.unv) with several frequency-response records: which one "
                 "(0-based, counting only the FRF records; coherences and spectra are "
                 "skipped); also which run of an LTspice export with .step runs, or "
                 "which sweep of a table of several (an impedance analyser's cycles)")
        parser.add_argument(
            "--parameter", metavar="S21",
            help="Touchstone file (.s1p, .s2p, ..., .sNp, or version 2 .ts): which "
                 "parameter (default S11; S21 is the transfer from port 1 to port 2; S10,11 "
                 "for ten and more ports); also which S-parameter or receiver ratio of a "
                 "network analyser's CSV whose header names several (S21(REAL),S21(IMAG),"
                 "S11(REAL),...,A2/A1(REAL),...); and which variable of a .mat file "
                 "holding several responses beside one frequency axis (H21)")
    if records if weights is None else weights:
        parser.add_argument(
            "--weights", metavar="STATS.csv",
            help="weights of the data's frequencies: the <stem>.stats.csv that 'freqid frf' "
                 "writes beside its FRF (column weight: |H|^2/variance, mean 1), at the same "
                 "omega; or 'noise' (freqid fit): estimated from the data, for an "
                 "analyser's noise floor (a fit without weights, then one weighed by the "
                 "noise level its residual shows; twice the time)")
    return parser


def _record(text):
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a record number 0, 1, ..., got {text!r}")
    return value


def load_options(args):
    """The ``freq_unit`` and ``columns`` keywords of :func:`~freqid_casadi.io.loaders.load`,
    and ``record``, ``parameter`` and ``band`` when given.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments (absent options count as not given).
    """
    opts = dict(freq_unit=getattr(args, "freq_unit", None),
                columns=getattr(args, "columns", None))
    for key in ("record", "parameter", "band"):
        if getattr(args, key, None) is not None:
            opts[key] = getattr(args, key)
    return opts


#: Depth of nested :func:`notes_to_stderr` blocks (the outermost one prints).
_NOTE_DEPTH = [0]


@contextlib.contextmanager
def notes_to_stderr():
    """Within the block, :class:`~freqid_casadi.io.loaders.DataWarning` s are printed as
    ``note: ...`` lines on stderr after the block succeeds (none if it raises), the same
    text for several files once (:func:`grouped_notes`); other warnings are passed on
    unchanged. Nested in another such block, the notes are passed to the outer one (a
    command reading many files prints their notes together).

    Yields a list that holds the printed lines once the block has ended (for the report
    to record how the data were read; empty for a nested block)."""
    printed = []
    _NOTE_DEPTH[0] += 1
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", DataWarning)
            yield printed
    finally:
        _NOTE_DEPTH[0] -= 1
    notes = []
    for w in caught:
        if issubclass(w.category, DataWarning) and _NOTE_DEPTH[0] == 0:
            notes.append(" ".join(str(w.message).split()))
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    printed += grouped_notes(notes)
    for line in printed:
        sys.stderr.write(f"note: {line}\n")


#: A note that names its file first: ``'path' ...`` or ``'path': ...``.
_FILE_NOTE = re.compile(r"^'(?P<path>[^']+)'(?P<rest>:? .*)$")


def grouped_notes(notes):
    """The reader notes of several files, each text once: notes that differ only in the
    file they name (nine exports of one analyser: the same encoding, preamble and band)
    become one line naming the files, in the order first seen.

    Parameters
    ----------
    notes : sequence of str

    Returns
    -------
    list of str
    """
    groups = {}
    for text in notes:
        m = _FILE_NOTE.match(text)
        key, path = (m.group("rest"), m.group("path")) if m else (text, None)
        groups.setdefault(key, []).append(path)
    out = []
    for rest, paths in groups.items():
        if None in paths:                       # a note naming no file: once
            out.append(rest)
        elif len(paths) == 1:
            out.append(f"'{paths[0]}'{rest}")
        elif len(set(paths)) == 1:              # the records of one file (a UFF test)
            out.append(f"'{paths[0]}' (each of {len(paths)} responses){rest}")
        else:
            paths = list(dict.fromkeys(paths))
            shown = (f"'{paths[0]}' ... '{paths[-1]}'" if len(paths) > 3
                     else ", ".join(f"'{p}'" for p in paths))
            out.append(f"{shown} (each of {len(paths)} files){rest}")
    return out


def refuse_flags(path, opts):
    """:func:`~freqid_casadi.io.loaders.refuse_options` of the load options ``opts``
    (:func:`load_options`) for ``path``, spelt as the command line's options
    (``--columns``).

    Parameters
    ----------
    path : str
        The data file.
    opts : dict
        :func:`load_options` of the parsed arguments.

    Raises
    ------
    OptionError
        An option that does not apply to ``path``'s kind of file.
    """
    refuse_options(path, record=opts.get("record"), parameter=opts.get("parameter"),
                   columns=opts.get("columns"), flag=True)


def load_data(args, path, noise_weights=False, notes=None):
    """Load ``path`` with the options in ``args``; reader notes go to stderr as ``note:``.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments with ``freq_unit`` and ``columns`` (see :func:`load_options`).
    path : str
        The data file.
    noise_weights : bool
        The command takes ``--weights noise`` (the data are returned without weights;
        the command passes ``weights="noise"`` to the fit); else it is refused.
    notes : list, optional
        Receives the notes printed (how the file was read), for the report.

    Returns
    -------
    FrequencyData

    Raises
    ------
    DataError, OptionError
        As :func:`freqid_casadi.io.loaders.load`; no note is printed before an error.
    """
    opts = load_options(args)
    refuse_flags(path, opts)
    with notes_to_stderr() as printed:
        data = load(path, **opts)
    if notes is not None:
        notes += printed
    weights = getattr(args, "weights", None)
    if weights == NOISE_WEIGHTS:
        if not noise_weights:
            raise OptionError("--weights noise applies to freqid fit (the weights estimated "
                              "from the data); here pass a weights file (STATS.csv) or "
                              "drop --weights")
        return data
    return data if weights is None else with_weights(data, weights)


#: ``--weights noise``: the weights estimated from the data (``fit(weights="noise")``); a
#: file of that name is read as ``./noise``.
NOISE_WEIGHTS = "noise"


def with_weights(data, path):
    """``data`` with the weights of a ``freqid frf`` sidecar (columns ``omega``, ``weight``).

    Parameters
    ----------
    data : FrequencyData
    path : str
        The ``<stem>.stats.csv`` file; its omega (rad/s) must be the data's.

    Raises
    ------
    DataError
        Not such a file, or its frequencies are not the data's.
    """
    path, payload = read_regular_file(path, "weights file")
    lines = [t for t in decode_text(path, payload).splitlines()
             if t.strip() and not t.startswith("#")]
    head = [c.strip().lower() for c in lines[0].split(",")] if lines else []
    if "omega" not in head or "weight" not in head:
        raise DataError(f"{path!r}: a weights file needs the columns omega and weight (the "
                        "<stem>.stats.csv that freqid frf writes beside its FRF)")
    try:
        cells = [[c.strip() for c in t.split(",")] for t in lines[1:]]
        if not all(NUMBER.fullmatch(c) for row in cells for c in row):
            raise ValueError
        table = np.array(cells, float)
        omega, weight = table[:, head.index("omega")], table[:, head.index("weight")]
    except (ValueError, IndexError):
        raise DataError(f"{path!r}: not a table of numbers under its header; pass the "
                        "<stem>.stats.csv that freqid frf wrote") from None
    if omega.shape != data.omega.shape or not np.allclose(omega, data.omega, rtol=1e-12,
                                                          atol=0):
        raise DataError(f"{path!r}: its {omega.size} frequencies are not the data's "
                        f"{data.n_points}; pass the .stats.csv written with this FRF")
    try:
        return FrequencyData(data.omega, data.response, data.name, weight)
    except DataError as exc:
        raise DataError(f"{path!r}: {exc}") from None


def error_line(message):
    """Write ``error: <message>`` (one line) to stderr.

    Parameters
    ----------
    message : str or Exception
        Its whitespace is collapsed to single spaces.
    """
    sys.stderr.write(f"error: {' '.join(str(message).split())}\n")
    sys.stderr.flush()


def os_exit(exc):
    """Exit status of an OSError: the error line and 2, or for a closed pipe (``freqid fit
    ... | head``) nothing more written and 141 (128 + SIGPIPE, as other tools).

    Parameters
    ----------
    exc : OSError

    Returns
    -------
    int
    """
    if isinstance(exc, BrokenPipeError):
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):
            pass
        return 141
    what = exc.strerror or str(exc)
    error_line(f"{what}: {exc.filename!r}" if exc.filename else what)
    return 2


# ----------------------------------------------------------------------------- arg types


_ASCII_INT = re.compile(r"[+-]?[0-9]+")
_ASCII_FLOAT = re.compile(r"[+-]?(([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?|nan|inf(inity)?)",
                          re.IGNORECASE)


def _ascii(pattern, convert):
    """``convert`` that first requires ``pattern`` (no "1_0", no non-ASCII digits)."""
    def checked(text):
        if not pattern.fullmatch(text.strip()):
            raise ValueError(text)
        return convert(text)
    return checked


def _checked(text, convert, valid, bad_type, bad_value):
    """``convert(text)`` if ``valid`` of it, else an ArgumentTypeError: ``bad_type`` (text)
    when it does not convert, ``bad_value(value)`` when it is out of range."""
    try:
        value = convert(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{bad_type}, got {text!r}") from None
    if not valid(value):
        raise argparse.ArgumentTypeError(bad_value(value))
    return value


def _positive_int(text):
    return _checked(text, _ascii(_ASCII_INT, int), lambda v: v >= 1, "must be a positive integer",
                    lambda v: f"must be a positive integer (>= 1), got {v}")


def _positive_float(text):
    return _checked(text, _ascii(_ASCII_FLOAT, float), lambda v: math.isfinite(v) and v > 0,
                    "must be a number > 0",
                    lambda v: f"must be a finite number > 0, got {text!r}")


# ----------------------------------------------------------------------------- option groups


#: --flag -> (choices, default, help) of the fit's options that take one of a set of words
_CHOICE_OPTIONS = {
    "--method": (METHODS, "ipopt", "stage solver: IPOPT with bounds or the thesis's "
                                   "log-barrier Levenberg-Marquardt"),
    "--start": (STARTS, "sequential", "sequential: the thesis's main loop; rational: vector "
                                      "fitting of all sections then one IPOPT polish; best: "
                                      "both, a converged model within 10 %% of the lowest max "
                                      "error wins"),
    "--objective": (OBJECTIVES, "least-squares", "minimax adds a polish of the max relative "
                                                 "error (kept only if it lowers it)"),
    "--gain-sign": (GAIN_SIGNS, "auto", "sign of the gain (auto: from the "
                                        "low-frequency phase; a sign-inverted system is "
                                        "fitted with a negative gain and said so)"),
    "--zeros": (ZEROS, "minimum-phase", "minimum-phase or free: zeros anywhere, "
                                        "poles stable (for excess phase a delay cannot "
                                        "explain)"),
}


def _add_final_max_iter(p):
    """``--final-max-iter N`` (:func:`method_option` reads it)."""
    p.add_argument("--final-max-iter", type=_positive_int, default=None, metavar="N",
                   help="iteration limit of the final all-data stage (default 200); a fit "
                        "that stops there says so and gives the N to continue with")


def method_option(args):
    """The fit's ``method`` from ``--method`` and ``--final-max-iter``: the method's name,
    or its options object with that iteration limit.

    Parameters
    ----------
    args : argparse.Namespace
        With ``method`` and ``final_max_iter`` (None: not given).

    Returns
    -------
    str or IpoptOptions or BarrierLMOptions
    """
    if getattr(args, "final_max_iter", None) is None:
        return args.method
    return dataclasses.replace(solver_options(args.method), final_max_iter=args.final_max_iter)


#: The fit's keywords and the options of the commands that set them (:func:`cli_words`).
_FLAGS = {"n_sections": "--sections", "max_sections": "--max-sections",
          "integrator": "--integrator", "gain_sign": "--gain-sign", "zeros": "--zeros",
          "min_damping": "--min-damping", "start": "--start", "objective": "--objective",
          "basis": "--basis", "n_jobs": "--jobs"}
_KEYWORD = re.compile(r"(?<![\w'\[.])(" + "|".join(_FLAGS) +
                      r")=('[^']*'|True|False|k|-?\d+(?:\.\d+)?(?:e-?\d+)?)(?![\w(])")
_CONTINUE = re.compile(r"method=(?:IpoptOptions|BarrierLMOptions)\(final_max_iter=(\d+)\)")
_ALTERNATIVE = re.compile(r" ?\(?FitResult\.alternatives\['(?:zeros=free|min_damping=None)'\]"
                          r"(?: holds (?:that model|it))?\)?")
#: ``LoopOptions`` switches and the options of ``freqid fit`` that set them.
_LOOP = ((re.compile(r"(?:pass )?(?:loop=)?LoopOptions\(resolution_guard=False\)"),
          "pass --no-resolution-guard"),
         (re.compile(r"(?:pass )?(?:loop=)?LoopOptions\(hold_delay=False\)"),
          "--no-hold-delay"))
#: A held parameter, ``fixed={'dc_gain': K}``: ``--fix dc_gain=K``.
_FIXED = re.compile(r"fixed=\{'(\w+)': ([^{}]+?)\}")


def cli_words(text):
    """``text`` (a fit's message or summary) with its advice in the command's words:
    ``integrator=2`` as ``--integrator 2``, ``zeros='free'`` as ``--zeros free``,
    ``method=IpoptOptions(final_max_iter=2000)`` as ``--final-max-iter 2000``,
    ``loop=LoopOptions(resolution_guard=False)`` as ``--no-resolution-guard`` (and
    ``hold_delay`` as ``--no-hold-delay``); the Python-only pointers to
    ``FitResult.alternatives[...]`` (a report folder does not hold the alternative) are
    dropped, the option to pass stays.

    Parameters
    ----------
    text : str

    Returns
    -------
    str
    """
    def flag(m):
        key, value = m.group(1), m.group(2)
        if key == "integrator" and value in ("True", "False", "k"):
            return {"True": "--integrator 1", "False": "--integrator 0"}.get(
                value, "--integrator K")
        return f"{_FLAGS[key]} {value.strip(chr(39))}"
    text = _CONTINUE.sub(r"--final-max-iter \1", text)
    text = _ALTERNATIVE.sub("", text)
    for pattern, option in _LOOP:
        text = pattern.sub(option, text)
    text = _FIXED.sub(r"--fix \1=\2", text)
    return _KEYWORD.sub(flag, text)


def in_cli_words(result):
    """``result`` with its message and its diagnostics' messages in the command's words
    (:func:`cli_words`), for the report a command writes.

    Parameters
    ----------
    result : FitResult

    Returns
    -------
    FitResult
    """
    diagnostics = tuple(dataclasses.replace(d, message=cli_words(d.message))
                        for d in getattr(result, "diagnostics", ()) or ())
    return dataclasses.replace(result, message=cli_words(result.message or ""),
                               diagnostics=diagnostics)


def print_continue_hint(result):
    """Print the fit's advice to raise ``final_max_iter`` (its message names the Python
    option) as the command's option ``--final-max-iter N``, when the message gives it.

    Parameters
    ----------
    result : FitResult
    """
    found = re.search(r"final_max_iter=(\d+)\) to continue", result.message or "")
    if found:
        print(f"to continue: run the same command with --final-max-iter {found.group(1)}")


def _add_choices(p, *flags, defaults=None):
    """Add the options ``flags`` of :data:`_CHOICE_OPTIONS` to ``p``, in that order;
    ``defaults`` (flag -> value) overrides their defaults."""
    for flag in flags:
        choices, default, text = _CHOICE_OPTIONS[flag]
        default = (defaults or {}).get(flag, default)
        p.add_argument(flag, choices=choices, default=default,
                       help=f"{text} (default {default})")


def _common(p, *, out_required, start="sequential"):
    _add_choices(p, "--method", "--start", "--objective", defaults={"--start": start})
    _add_final_max_iter(p)
    if out_required:
        p.add_argument("--out", required=True, metavar="DIR",
                       help="report folder to create (must not exist unless --force)")
    else:
        p.add_argument("--out", metavar="DIR",
                       help="report folder to create (default: ./freqid_example_<X>)")
    p.add_argument("--force", action="store_true",
                   help="replace an existing report folder (after the new one is complete)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--progress", dest="progress", action="store_true", default=None,
                   help="print one line per stage to stderr (default: a bar on a "
                        "terminal, elsewhere a line per 30 s of a long run)")
    g.add_argument("--quiet", dest="progress", action="store_false",
                   help="no progress output")


def _integrator_arg(text):
    """``--integrator K|auto``: "auto" or an integer k with ``|k| <= MAX_ORIGIN_ORDER``."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        k = int(text.strip(), 10)
    except ValueError:
        k = None
    if k is None or abs(k) > MAX_ORIGIN_ORDER:
        raise argparse.ArgumentTypeError(
            f"must be auto or an integer k with |k| <= {MAX_ORIGIN_ORDER} (k poles at the "
            f"origin, -k zeros), got {text!r}; e.g. --integrator 2, --integrator -2")
    return bool(k) if k in (0, 1) else k


def _add_model_arguments(p, tol=True, integrator="auto"):
    """--integrator [K|auto], --no-delay, --basis (and --tol): the model structure of a
    fit (used by the fit, sweep and batch commands; ``integrator`` is the default when
    the flag is absent: "auto" for fit and sweep, False for batch)."""
    p.add_argument("--integrator", nargs="?", const=True, default=integrator,
                   type=_integrator_arg, metavar="K|auto",
                   help="poles at the origin: --integrator alone is the factor K0/s (k = 1); "
                        "--integrator K for k poles (negative: -k zeros, e.g. -2 for an "
                        "accelerance), |k| <= 3; --integrator auto chooses k from the data "
                        f"(default {'auto' if integrator == 'auto' else 'none'})")
    p.add_argument("--no-delay", dest="delay", action="store_false",
                   help="fix the delay h at 0")
    _add_loop_switches(p)
    p.add_argument("--basis", choices=BASES, default="second-order",
                   help="section type (default second-order)")
    if tol:
        p.add_argument("--tol", type=_positive_float, metavar="X",
                       help="stop adding sections once the max relative error is below X")


def _add_loop_switches(p):
    """``--no-resolution-guard`` and ``--no-hold-delay`` (:func:`loop_option`)."""
    p.add_argument("--no-resolution-guard", dest="resolution_guard", action="store_false",
                   help="keep the fit as asked for when a pole or zero is narrower than the "
                        "frequency spacing (by default a refit with the damping floor of "
                        "the spacing is kept when it explains the data as well)")
    p.add_argument("--no-hold-delay", dest="hold_delay", action="store_false",
                   help="keep the free fit's delay when the data do not determine it (by "
                        "default it is held at a simpler fit's value when that explains "
                        "the data as well)")


def loop_option(args):
    """``{"loop": LoopOptions(...)}`` of ``--no-resolution-guard`` / ``--no-hold-delay``
    (:func:`_add_model_arguments`), or ``{}`` (the fit's default loop).

    Parameters
    ----------
    args : argparse.Namespace

    Returns
    -------
    dict
    """
    off = {k: False for k in ("resolution_guard", "hold_delay")
           if getattr(args, k, True) is False}
    return {"loop": LoopOptions(**off)} if off else {}


def _add_input(p, name, metavar, text, records=False):
    """The positional data input ``name`` and the data-file options (``--freq-unit``,
    ``--columns``; with ``records`` ``--record``, ``--parameter``) of a command that reads
    data (fit, sweep, batch)."""
    p.add_argument(name, metavar=metavar, help=text)
    add_data_options(p, records)


# ----------------------------------------------------------------------------- output


def _progress(args):
    return True if args.progress is None else ("lines" if args.progress else False)


# a number in the console tables: "-" when missing
_g = partial(number, missing="-")


def _resolution_warning(result):
    check = getattr(result, "resolution", None)
    if check is not None and not check.ok:
        exact = result.rms_rel_error <= ROUNDING_RMS      # spare sections, not noise
        print(f"warning: {len(check.flags)} near-cancelling pole/zero pair(s) and "
              f"{len(check.unresolved)} unresolved pole(s)/zero(s) are narrower than the "
              "frequency spacing (not determined by the data); " + (
                  "the fit is exact to rounding, so they are spare sections: fit fewer "
                  "sections, or prune them with "
                  "freqid_casadi.fitting.validation.prune_sections" if exact else
                  "refit with --min-damping auto, fit fewer sections, or prune them with "
                  "freqid_casadi.fitting.validation.prune_sections"))

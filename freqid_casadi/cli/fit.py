"""The ``freqid fit`` command: fit a model to frequency-response data from a file (layer 10).

::

    freqid fit FILE --sections N|auto [--max-sections N] [--integrator [K|auto]] [--no-delay]
               [--basis B] [--tol X] [--gain-sign S] [--zeros Z] [--min-damping auto|ZETA]
               [--fix KEY=VALUE] [--jobs N] [--final-max-iter N] [--method M] [--start S]
               [--objective O] --out DIR [--force]

Reads the file (:func:`freqid_casadi.cli.common.load_data`), fits it
(:func:`freqid_casadi.fitting.fit.fit`, through ``app.fit``), writes a report folder and
prints the result's summary.
"""

import argparse
import math
import warnings

from . import app
from .common import (_ASCII_FLOAT, _add_choices, _add_input, _add_model_arguments, _ascii,
                     _checked, _common, _positive_int, _progress, _resolution_warning,
                     NOISE_WEIGHTS, cli_words, in_cli_words, load_data, loop_option,
                     method_option, print_continue_hint)
from ..errors import OptionError, ResolutionWarning
from .._validate import check_jobs
from ..fitting.fixed import FIXED_KEYS
from ..report.folder import check_out_dir, write_fit_report

__all__ = ["add_cli", "run_cli"]


def _sections_or_auto(text):
    if text == "auto":
        return "auto"
    try:
        return _positive_int(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"must be a positive integer or 'auto', got {text!r}") from None


def _min_damping(text):
    what = "must be 'auto' or a damping ratio in [0, 1)"
    return "auto" if text == "auto" else _checked(
        text, _ascii(_ASCII_FLOAT, float), lambda v: math.isfinite(v) and 0 <= v < 1, what,
        lambda v: f"{what}, got {text!r}")


def _fix_pair(text):
    """``KEY=VALUE`` of ``--fix`` as ``(key, float)``; KEY one of FIXED_KEYS."""
    what = f"must be KEY=VALUE with KEY one of {', '.join(FIXED_KEYS)}, e.g. delay=0.0123"
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or key not in FIXED_KEYS:
        raise argparse.ArgumentTypeError(f"{what}, got {text!r}")
    return key, _checked(value, _ascii(_ASCII_FLOAT, float), math.isfinite,
                         f"{what} (VALUE a number)", lambda v: f"{what}, got {text!r}")


_FILES = ("Text files: comma, semicolon, tab or space separated; the header names each "
          "column and its unit: omega (rad/s), freq_hz or 'Frequency (Hz)' (Hz), f/freq "
          "(unit from --freq-unit); re,im or mag/mag_db with phase_deg/phase_rad; e.g. "
          "'Frequency (Hz),Magnitude (dB),Phase (deg)'. No header: --freq-unit and, unless "
          "the columns are frequency,real,imag, --columns.")


def add_cli(sub):
    """Add the ``fit`` subparser to ``sub`` (the ``freqid`` subparsers); return it.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``freqid`` command's subparsers.
    """
    p = sub.add_parser("fit", help="fit a model to frequency-response data from a file",
                       description="Fit G_N(s) = exp(-hs) K [1/s] P_N(s) to data read from "
                                   "a file and write a report folder. " + _FILES)
    _add_input(p, "file", "FILE",
               "data file: text/CSV, .npz, .mat, .uff/.unv, Touchstone .s1p/.s2p/.../.sNp or .ts",
               records=True)
    p.add_argument("--sections", type=_sections_or_auto, required=True, metavar="N|auto",
                   help="number of sections N >= 1, or 'auto': the smallest order whose "
                        "residual is consistent with the noise (up to --max-sections)")
    p.add_argument("--max-sections", type=_positive_int, default=None, metavar="N",
                   help="with --sections auto: the largest order tried (default 16)")
    _add_model_arguments(p)
    _add_choices(p, "--gain-sign", "--zeros")
    add_min_damping(p, "for noisy data: no pole/zero pair narrower than the spacing")
    p.add_argument("--fix", type=_fix_pair, action="append", metavar="KEY=VALUE",
                   help="hold a known parameter exactly (repeatable): delay=H (s) or "
                        "dc_gain=K (K0 with --integrator, else G(0))")
    p.add_argument("--jobs", "--n-jobs", dest="jobs", type=_jobs, default=1, metavar="N",
                   help="worker processes for the fits a fit compares: the automatic "
                        "integrator's contenders, both gain signs when the starts do not "
                        "decide it (default 1; -1: every core; the same model whatever N)")
    # a user's data: both starts (the sequential loop alone can end in a valley the
    # rational start avoids, e.g. a zero pair drifting to infinity against the delay; the
    # loop is skipped when the rational start already reaches the noise)
    _common(p, out_required=True, start="best")
    return p


def add_min_damping(p, note):
    """``--min-damping auto|ZETA`` (fit's ``min_damping``), ``note`` closing its help.

    Parameters
    ----------
    p : argparse.ArgumentParser
    note : str
    """
    p.add_argument("--min-damping", type=_min_damping, metavar="auto|ZETA",
                   help="floor on the damping ratio of every pole and zero; 'auto' ties it "
                        f"to the frequency spacing ({note})")


def _jobs(text):
    """``--jobs``: a positive integer or -1 (every core), as fit's ``n_jobs``."""
    try:
        value = int(text)
        check_jobs(value, every_core=True)
    except (ValueError, OptionError):
        raise argparse.ArgumentTypeError(f"expected a positive integer or -1 (every core), "
                                         f"got {text!r}") from None
    return value


def run_cli(args, command):
    """Run ``freqid fit``; print the summary and the report folder; return 0.

    The fit goes through ``app.fit`` (the one seam the tests replace).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed ``freqid fit`` arguments.
    command : str
        The command line, written as the first line of the report.
    """
    notes = []                                        # how the file was read, for the report
    data = load_data(args, args.file, noise_weights=True, notes=notes)   # DataError if bad
    check_out_dir(args.out, args.force)              # before the (long) fit
    if args.max_sections is not None:
        if args.sections != "auto":
            raise OptionError(f"--max-sections {args.max_sections} applies only to --sections "
                              f"auto, got --sections {args.sections}; drop --max-sections "
                              "or pass --sections auto")
        args.sections = range(1, args.max_sections + 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResolutionWarning)   # reported below, one line
        result = app.fit(data, n_sections=args.sections, integrator=args.integrator,
                         delay=args.delay, basis=args.basis, method=method_option(args),
                         tol=args.tol,
                         progress=_progress(args), start=args.start, objective=args.objective,
                         min_damping=args.min_damping, gain_sign=args.gain_sign,
                         zeros=args.zeros, **({"fixed": dict(args.fix)} if args.fix else {}),
                         **({"n_jobs": args.jobs} if args.jobs != 1 else {}),
                         **loop_option(args),
                         **({"weights": NOISE_WEIGHTS} if args.weights == NOISE_WEIGHTS
                            else {}))
    _resolution_warning(result)
    path = write_fit_report(in_cli_words(result), args.out, command=command,
                            force=args.force, data_notes=notes)
    print(cli_words(result.summary()))
    print_continue_hint(result)
    print(f"report: {path}")
    return 0

"""The ``freqid`` command line (layer L6).

Commands::

    freqid example {A,B,C,fractional} [--sections N] [--method M] [--out DIR] [--force]
    freqid fit FILE --sections N [--integrator [K|auto]] [--no-delay] [--basis B] [--method M]
                    [--gain-sign S] [--zeros Z] [--tol X] --out DIR [--force]
    freqid sweep FILE|example:X --orders SPEC [--target X] --out DIR
    freqid ablation [--examples LIST] [--quick] [--out DIR]     (cli_ablation)
    freqid reproduce [--examples LIST] [--quick] [--out DIR]    (studies.reproduce_report)
    freqid frf ..., freqid batch ..., freqid modal ...   (cli_frf, cli_batch, cli_modal)

Each command parses its arguments, calls the API (:func:`freqid_casadi.fitting.fit.fit`), writes a
report folder (:func:`freqid_casadi.report.folder.write_fit_report`) and prints a short summary.
Progress (one line per stage) goes to stderr when stderr is a terminal, or with
``--progress``; ``--quiet`` silences it.

Errors: a :class:`~freqid_casadi.errors.FreqidError`, an ``OSError`` while writing, or a
usage error prints one line ``error: <message>`` to stderr and returns 2;
KeyboardInterrupt prints ``error: interrupted`` and returns 130. No traceback is shown for
either, and no partial report is left behind.

New commands add one ``_add_<name>`` parser function and one ``_cmd_<name>`` function and
register them in :data:`COMMANDS`.
"""

import argparse
import math
import os
import re
import shlex
import sys
import warnings
from functools import partial

from .. import _interrupt, _textio
from ..report import outputs as _outputs
from .common import add_data_options, load_data
from .common import error_line as _error, os_exit as _os_exit
from ..errors import FreqidError, OptionError, ResolutionWarning
from ..systems.examples import EXAMPLES, FRACTIONAL_SECTIONS
from ..fitting.fit import GAIN_SIGNS, METHODS, OBJECTIVES, STARTS, fit
from ..fitting.fixed import FIXED_KEYS
from ..report.formatting import number, text_table
from ..core.model import BASES, MAX_ORIGIN_ORDER, ZEROS
from ..report.folder import check_out_dir, dense_error, write_fit_report

__all__ = ["main", "build_parser", "EXAMPLES", "FRACTIONAL_SECTIONS", "PROG"]

PROG = "freqid"

class _UsageError(Exception):
    """A command-line usage error (reported as one ``error:`` line, exit code 2)."""


class _Parser(argparse.ArgumentParser):
    """argparse parser whose errors are one ``error: ...`` line, not usage + message."""

    def error(self, message):
        raise _UsageError(f"{message} (see '{self.prog} --help')")


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


def _positive_float(text):
    return _checked(text, _ascii(_ASCII_FLOAT, float), lambda v: math.isfinite(v) and v > 0,
                    "must be a number > 0",
                    lambda v: f"must be a finite number > 0, got {text!r}")


def _fix_pair(text):
    """``KEY=VALUE`` of ``--fix`` as ``(key, float)``; KEY one of FIXED_KEYS."""
    what = f"must be KEY=VALUE with KEY one of {', '.join(FIXED_KEYS)}, e.g. delay=0.0123"
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or key not in FIXED_KEYS:
        raise argparse.ArgumentTypeError(f"{what}, got {text!r}")
    return key, _checked(value, _ascii(_ASCII_FLOAT, float), math.isfinite,
                         f"{what} (VALUE a number)", lambda v: f"{what}, got {text!r}")


# ----------------------------------------------------------------------------- parser


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
                   help="print one line per stage to stderr (default when stderr is a "
                        "terminal)")
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
    p.add_argument("--basis", choices=BASES, default="second-order",
                   help="section type (default second-order)")
    if tol:
        p.add_argument("--tol", type=_positive_float, metavar="X",
                       help="stop adding sections once the max relative error is below X")


def _add_input(p, name, metavar, text, records=False):
    """The positional data input ``name`` and the data-file options (``--freq-unit``,
    ``--columns``; with ``records`` ``--record``, ``--parameter``) of a command that reads
    data (fit, sweep, batch)."""
    p.add_argument(name, metavar=metavar, help=text)
    add_data_options(p, records)


def _add_example(sub):
    p = sub.add_parser("example", help="fit a built-in example at the thesis's order",
                       description="Fit one of the thesis's examples (A, B, C: beams and "
                                   "rod, thesis ch. 4; fractional: 1/sqrt(s), §4.2) and "
                                   "write a report folder.")
    p.add_argument("name", choices=tuple(EXAMPLES), metavar="{" + ",".join(EXAMPLES) + "}",
                   help="which example")
    p.add_argument("--sections", type=_positive_int, metavar="N",
                   help="number of sections (default: the thesis's order; A 17, B 9, C 27, "
                        f"fractional {FRACTIONAL_SECTIONS} first-order)")
    # the thesis's loop (its published numbers); --start best or rational to compare
    _common(p, out_required=False, start="sequential")
    return p


_FILES = ("Text files: comma, semicolon, tab or space separated; the header names each "
          "column and its unit: omega (rad/s), freq_hz or 'Frequency (Hz)' (Hz), f/freq "
          "(unit from --freq-unit); re,im or mag/mag_db with phase_deg/phase_rad; e.g. "
          "'Frequency (Hz),Magnitude (dB),Phase (deg)'. No header: --freq-unit and, unless "
          "the columns are frequency,real,imag, --columns.")


def _add_fit(sub):
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
    p.add_argument("--min-damping", type=_min_damping, metavar="auto|ZETA",
                   help="floor on the damping ratio of every pole and zero; 'auto' ties it "
                        "to the frequency spacing (for noisy data: no pole/zero pair "
                        "narrower than the spacing)")
    p.add_argument("--fix", type=_fix_pair, action="append", metavar="KEY=VALUE",
                   help="hold a known parameter exactly (repeatable): delay=H (s) or "
                        "dc_gain=K (K0 with --integrator, else G(0))")
    # a user's data: both starts (the sequential loop alone can end in a valley the
    # rational start avoids, e.g. a zero pair drifting to infinity against the delay)
    _common(p, out_required=True, start="best")
    return p


def _add_reproduce(sub):
    from ..studies.reproduce import EXAMPLE_NAMES

    p = sub.add_parser(
        "reproduce", help="reproduce the thesis's Table 4.1 and figures 4.1-4.21",
        description="Fit the thesis's examples with our method and the baselines and write "
                    "a report folder (report.md, report.json, figures).")
    p.add_argument("--out", default="results/thesis", metavar="DIR",
                   help="report folder to create (default results/thesis; must not exist "
                        "unless --force)")
    p.add_argument("--force", action="store_true",
                   help="replace an existing report folder (after the new one is complete)")
    p.add_argument("--quick", action="store_true",
                   help="tiny problems (about a minute) to test the report; numbers not "
                        "comparable with the thesis")
    p.add_argument("--examples", metavar="LIST",
                   help=f"comma-separated subset of {','.join(EXAMPLE_NAMES)} (default: all; "
                        "with --quick: A,fractional,moheimani)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--progress", dest="progress", action="store_true", default=None,
                   help="log each fit to stderr (default when stderr is a terminal)")
    g.add_argument("--quiet", dest="progress", action="store_false", help="no progress output")
    p.add_argument("--report-command", help=argparse.SUPPRESS)
    return p


def _cmd_reproduce(args, command):
    import logging

    from ..studies.reproduce_report import write_reproduce_report

    if _progress(args) and not logging.getLogger().handlers:
        logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s",
                            stream=sys.stderr)
    summary = write_reproduce_report(args.out, command=args.report_command or command,
                                     force=args.force, quick=args.quick,
                                     examples=args.examples)
    table = summary.get("table_4_1") or {}
    for row in table.get("rows", []):
        if row["quantity"] == "max_rel_error":
            cells = ", ".join(f"{c}={number(v)}" for c, v in zip(table["columns"],
                                                                 row["values"]))
            print(f"{row['example']}: max rel. error: {cells}")
    print(f"report: {os.path.abspath(args.out)} ({summary['wall_time']:.0f} s)")
    return 0


#: name -> (add parser, run command)
COMMANDS = {}


def build_parser():
    """The argparse parser of the ``freqid`` command (one subparser per command)."""
    parser = _Parser(prog=PROG, description="Stable, minimum-phase low-order models with "
                                            "delay from frequency-response data.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True,
                                parser_class=_Parser)
    for name, (add, _) in COMMANDS.items():
        add(sub).set_defaults(_run=name)
    return parser


# ----------------------------------------------------------------------------- commands


def _progress(args):
    return True if args.progress is None else ("lines" if args.progress else False)


# a number in the console tables: "-" when missing
_g = partial(number, missing="-")


def _cmd_example(args, command):
    ex = EXAMPLES[args.name]
    out = args.out or f"freqid_example_{args.name}"
    check_out_dir(out, args.force)                   # before the (long) fit
    structure = ex.structure(args.sections)
    data = ex.data()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResolutionWarning)   # reported below, one line
        result = fit(data, **structure, method=args.method, progress=_progress(args),
                     start=args.start, objective=args.objective)
    thesis = ex.thesis.as_dict() if ex.thesis is not None else None
    path = write_fit_report(result, out, command=command, force=args.force,
                            title=f"Example {args.name}: {data.name}", thesis=thesis,
                            truth=ex.truth)
    dense = dense_error(result.model, data.omega, ex.truth)
    t = thesis or {}
    per = 2 if ex.basis == "second-order" else 1
    row = (args.name, per * structure["n_sections"], _g(result.max_rel_error),
           _g(dense["max_rel_error"]), _g(result.rms_rel_error),
           _g(result.model.delay), f"{result.wall_time:.1f}",
           t.get("order", "-"), _g(t.get("max_rel_error")), _g(t.get("delay")))
    print(result.message)
    print(text_table([row], ("example", "order", "max rel. err", "10x grid",
                              "RMS rel. err", "delay (s)", "time (s)", "thesis order",
                              "thesis max", "thesis delay")))
    _resolution_warning(result)
    print(f"report: {path}")
    return 0


def _resolution_warning(result):
    check = getattr(result, "resolution", None)
    if check is not None and not check.ok:
        print(f"warning: {len(check.flags)} near-cancelling pole/zero pair(s) and "
              f"{len(check.unresolved)} unresolved pole(s)/zero(s) are narrower than the "
              "frequency spacing (not determined by the data); refit with --min-damping auto, "
              "fit fewer sections, or prune them with freqid_casadi.fitting.validation.prune_sections")


def _cmd_fit(args, command):
    data = load_data(args, args.file)                # DataError on bad files
    check_out_dir(args.out, args.force)              # before the (long) fit
    if args.max_sections is not None:
        if args.sections != "auto":
            raise OptionError(f"--max-sections {args.max_sections} applies only to --sections "
                              f"auto, got --sections {args.sections}; drop --max-sections "
                              "or pass --sections auto")
        args.sections = range(1, args.max_sections + 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResolutionWarning)   # reported below, one line
        result = fit(data, n_sections=args.sections, integrator=args.integrator,
                     delay=args.delay, basis=args.basis, method=args.method, tol=args.tol,
                     progress=_progress(args), start=args.start, objective=args.objective,
                     min_damping=args.min_damping, gain_sign=args.gain_sign,
                     zeros=args.zeros, **({"fixed": dict(args.fix)} if args.fix else {}))
    _resolution_warning(result)
    path = write_fit_report(result, args.out, command=command, force=args.force)
    print(result.summary())
    print(f"report: {path}")
    return 0


def _add_sweep(sub):
    p = sub.add_parser("sweep", help="fit every order of a range; find the smallest that "
                                     "meets a target",
                       description="Fit the data at each order of P_N and write a table "
                                   "(sweep.md, sweep.csv, sweep.json) and a figure of "
                                   "order vs max relative error, delay and time.")
    _add_input(p, "file", "FILE", "data file (as for 'freqid fit'), or example:A (B, C) for "
                                  "a built-in example (then the error on a 10x denser grid "
                                  "is reported too)", records=True)
    p.add_argument("--orders", required=True, metavar="START:STOP:STEP",
                   help="orders of P_N, e.g. 4:40:2 (stop included) or 10,20,34")
    p.add_argument("--target", type=_positive_float, metavar="X",
                   help="name the smallest order whose max relative error is <= X")
    _add_model_arguments(p, tol=False)
    p.add_argument("--method", choices=METHODS, default="ipopt")
    p.add_argument("--start", choices=STARTS, default="best")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--force", action="store_true")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    return p


def _cmd_sweep(args, command):
    from ..fitting.sweep import parse_orders, sweep
    from ..report.folder import write_sweep_report

    orders = parse_orders(args.orders)
    truth = None
    integrator = args.integrator
    if args.file.startswith("example:"):
        name = args.file.split(":", 1)[1]
        if name not in ("A", "B", "C"):
            raise OptionError(f"unknown example {name!r} in {args.file!r}; use example:A, "
                              "example:B or example:C")
        data = EXAMPLES[name].data()
        truth = EXAMPLES[name].truth
        if integrator == "auto":                   # the example's own structure
            integrator = EXAMPLES[name].integrator
    else:
        data = load_data(args, args.file)
    check_out_dir(args.out, args.force)

    def report(row):
        if not args.quiet:
            sys.stderr.write(f"order {row.order}: max rel. error {row.max_rel_error:.3e}, "
                             f"delay {row.delay:.6g} {data.time_unit}, "
                             f"{row.wall_time:.1f} s\n")

    result = sweep(data, orders, target=args.target, truth=truth, progress=report,
                   integrator=integrator, delay=args.delay, basis=args.basis,
                   method=args.method, start=args.start)
    path = write_sweep_report(result, args.out, command=command, force=args.force)
    rows = [(r.order, _g(r.max_rel_error), _g(r.rms_rel_error), _g(r.max_rel_error_dense),
             _g(r.delay, 6), f"{r.wall_time:.1f}") for r in result.rows]
    print(text_table(rows, ("order", "max rel. err", "RMS", "max (10x grid)", "delay (s)",
                             "time (s)")))
    if args.target is not None:
        print(f"smallest order with max rel. error <= {args.target:g}: "
              f"{result.best_order if result.best_order is not None else 'none'}")
    print(f"report: {path}")
    return 0


COMMANDS["example"] = (_add_example, _cmd_example)
COMMANDS["fit"] = (_add_fit, _cmd_fit)
COMMANDS["reproduce"] = (_add_reproduce, _cmd_reproduce)
COMMANDS["sweep"] = (_add_sweep, _cmd_sweep)


def _plugin(module_name):
    """(add, run) of a command whose parser and runner live in another module, which is
    imported only when that command runs or the parser is built."""
    import importlib

    def add(sub):
        mod = importlib.import_module(f"{__package__}.{module_name}")
        before = set(sub.choices)
        mod.add_cli(sub)
        (name,) = set(sub.choices) - before
        return sub.choices[name]

    def run(args, command):
        mod = importlib.import_module(f"{__package__}.{module_name}")
        return mod.run_cli(args, command)

    return add, run


COMMANDS["ablation"] = _plugin("ablation")
COMMANDS["frf"] = _plugin("frf")
COMMANDS["batch"] = _plugin("batch")
COMMANDS["modal"] = _plugin("modal")


# ----------------------------------------------------------------------------- main


def main(argv=None):
    """Run the ``freqid`` command line.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name (default ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success, 2 on a usage, data or option error, 130 when interrupted by Ctrl-C,
        143 by SIGTERM.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    command = " ".join([PROG] + [shlex.quote(a) for a in argv])
    _textio.printable_streams()                          # undecodable file names stay printable
    try:
        try:
            args = build_parser().parse_args(argv)
        except SystemExit as exc:                    # --help, --version
            return exc.code if isinstance(exc.code, int) else 0
        inputs = [getattr(args, a, None) for a in ("file", "folder", "records")]
        with _interrupt.handlers(), _outputs.inputs(_outputs.input_paths(inputs)):
            return _textio.run_holding_warnings(COMMANDS[args._run][1], args, command)
    except _UsageError as exc:
        _error(exc)
        return 2
    except FreqidError as exc:
        _error(exc)
        return 2
    except OSError as exc:
        return _os_exit(exc)
    except KeyboardInterrupt as exc:
        _error("interrupted")
        return _interrupt.exit_status(exc)
    except (MemoryError, RecursionError, ArithmeticError, ValueError, TypeError) as exc:
        _error(f"internal error ({type(exc).__name__}: {exc}); please report it with the "
               "command line")
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

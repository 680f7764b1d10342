"""The ``freqid example`` command: fit a built-in example at the thesis's order (layer 10).

::

    freqid example {A,B,C,fractional} [--sections N] [--method M] [--start S]
                   [--final-max-iter N] [--out DIR] [--force]

Fits the example's data with the thesis's loop (``--start sequential``, its published
numbers), writes a report folder (:func:`freqid_casadi.report.folder.write_fit_report`)
with the thesis's numbers beside ours and prints a one-row table.
"""

import warnings

from . import app
from .common import (_common, _g, _positive_int, _progress, _resolution_warning,
                     _add_loop_switches, cli_words, in_cli_words, loop_option, method_option,
                     print_continue_hint)
from .fit import add_min_damping
from ..errors import ResolutionWarning
from ..report.folder import check_out_dir, dense_error, write_fit_report
from ..report.formatting import text_table
from ..systems.examples import EXAMPLES, FRACTIONAL_SECTIONS

__all__ = ["add_cli", "run_cli"]


def add_cli(sub):
    """Add the ``example`` subparser to ``sub`` (the ``freqid`` subparsers); return it.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``freqid`` command's subparsers.
    """
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
    add_min_damping(p, "default none: the thesis's fit")
    _add_loop_switches(p)
    return p


def run_cli(args, command):
    """Run ``freqid example``; print the message, the table and the report folder; return 0.

    The fit goes through ``app.fit`` (the one seam the tests replace).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed ``freqid example`` arguments.
    command : str
        The command line, written as the first line of the report.
    """
    ex = EXAMPLES[args.name]
    out = args.out or f"freqid_example_{args.name}"
    check_out_dir(out, args.force)                   # before the (long) fit
    structure = ex.structure(args.sections)
    data = ex.data()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResolutionWarning)   # reported below, one line
        result = app.fit(data, **structure, method=method_option(args),
                         progress=_progress(args),
                         start=args.start, objective=args.objective,
                         **({"min_damping": args.min_damping}
                            if args.min_damping is not None else {}), **loop_option(args))
    thesis = ex.thesis.as_dict() if ex.thesis is not None else None
    path = write_fit_report(in_cli_words(result), out, command=command,
                            force=args.force, title=f"Example {args.name}: {data.name}",
                            thesis=thesis, truth=ex.truth)
    dense = dense_error(result.model, data.omega, ex.truth)
    t = thesis or {}
    per = 2 if ex.basis == "second-order" else 1
    row = (args.name, per * structure["n_sections"], _g(result.max_rel_error),
           _g(dense["max_rel_error"]), _g(result.rms_rel_error),
           _g(result.model.delay), f"{result.wall_time:.1f}",
           t.get("order", "-"), _g(t.get("max_rel_error")), _g(t.get("delay")))
    print(cli_words(result.message))
    print(text_table([row], ("example", "order", "max rel. err", "10x grid",
                              "RMS rel. err", "delay (s)", "time (s)", "thesis order",
                              "thesis max", "thesis delay")))
    _resolution_warning(result)
    print_continue_hint(result)
    print(f"report: {path}")
    return 0

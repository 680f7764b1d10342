"""The ``freqid sweep`` command: fit every order of a range (layer 10).

::

    freqid sweep FILE|example:X --orders START:STOP:STEP [--target X] [--integrator [K|auto]]
                 [--no-delay] [--basis B] [--method M] [--start S] --out DIR [--force]
                 [--quiet]

Fits each order (:func:`freqid_casadi.fitting.sweep.sweep`), writes sweep.md, sweep.csv,
sweep.json and a figure (:func:`freqid_casadi.report.folder.write_sweep_report`), prints
the table and, with ``--target``, the smallest order that meets it.
"""

import sys

from .common import (_add_choices, _add_input, _add_model_arguments, _g, _positive_float,
                     load_data, loop_option)
from ..errors import OptionError
from ..report.folder import check_out_dir
from ..report.formatting import text_table
from ..systems.examples import EXAMPLES

__all__ = ["add_cli", "run_cli"]


def add_cli(sub):
    """Add the ``sweep`` subparser to ``sub`` (the ``freqid`` subparsers); return it.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``freqid`` command's subparsers.
    """
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
    _add_choices(p, "--method", "--start", defaults={"--start": "best"})
    p.add_argument("--out", required=True, metavar="DIR",
                   help="report folder to create (must not exist unless --force)")
    p.add_argument("--force", action="store_true",
                   help="replace an existing report folder (after the new one is complete)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--quiet", action="store_true", help="no progress lines")
    g.add_argument("--progress", dest="quiet", action="store_false",
                   help="one progress line per order on stderr (the default)")
    return p


def run_cli(args, command):
    """Run ``freqid sweep``; progress lines on stderr unless ``--quiet``; return 0.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed ``freqid sweep`` arguments.
    command : str
        The command line, written as the first line of the report.
    """
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
            sys.stderr.write(f"order {row.order}: {row.status}, max rel. error "
                             f"{row.max_rel_error:.3e}, "
                             f"delay {row.delay:.6g} {data.time_unit}, "
                             f"{row.wall_time:.1f} s\n")

    result = sweep(data, orders, target=args.target, truth=truth, progress=report,
                   integrator=integrator, delay=args.delay, basis=args.basis,
                   method=args.method, start=args.start, **loop_option(args))
    path = write_sweep_report(result, args.out, command=command, force=args.force)
    rows = [(r.order, _g(r.max_rel_error), _g(r.rms_rel_error), _g(r.max_rel_error_dense),
             _g(r.delay, 6), f"{r.wall_time:.1f}", str(r.status)) for r in result.rows]
    print(text_table(rows, ("order", "max rel. err", "RMS", "max (10x grid)", "delay (s)",
                             "time (s)", "status")))
    if args.target is not None:
        best = next((r for r in result.rows if r.order == result.best_order), None)
        how = "" if best is None or str(best.status) == "ok" else (
            f" (status {best.status}: its error is measured, the fit did not "
            f"{'converge' if str(best.status) == 'not-converged' else 'reach the noise'})")
        print(f"smallest order with max rel. error <= {args.target:g}: "
              f"{result.best_order if result.best_order is not None else 'none'}{how}")
    print(f"report: {path}")
    return 0

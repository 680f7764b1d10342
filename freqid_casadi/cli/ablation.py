"""The ``freqid ablation`` command: IPOPT vs the thesis's barrier-LM, and IPOPT's options
one at a time (layer L7; the study is :mod:`freqid_casadi.studies.ablation`).

Registered in :data:`freqid_casadi.cli.app.COMMANDS` (its :func:`add_cli` and :func:`run_cli`).
"""

import argparse

from ..systems.examples import EXAMPLES
from ..report.folder import check_out_dir

__all__ = ["add_cli", "run_cli", "NAME"]

#: Name of the command.
NAME = "ablation"


def _example_list(text):
    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in EXAMPLES]
    if not names or unknown:
        raise argparse.ArgumentTypeError(
            f"must be a comma-separated list of {', '.join(EXAMPLES)}, got {text!r}")
    return list(dict.fromkeys(names))


def add_cli(subparsers):
    """Add the ``ablation`` subparser to ``subparsers``; return it.

    Parameters
    ----------
    subparsers : argparse._SubParsersAction
        The ``freqid`` command's subparsers.
    """
    p = subparsers.add_parser("ablation", help="IPOPT vs the thesis's barrier-LM, and IPOPT's "
                                        "options one at a time",
                       description="Fit the built-in examples at the thesis's orders with "
                                   "IPOPT and the barrier-LM, and with IPOPT's options "
                                   "changed one at a time; write report.md, ablation.json "
                                   "and figures. Long: about 15-30 minutes for all examples.")
    p.add_argument("--examples", type=_example_list, metavar="LIST",
                   help=f"comma-separated examples (default: all, {','.join(EXAMPLES)}; "
                        "with --quick: A,fractional)")
    p.add_argument("--quick", action="store_true",
                   help="small problems (300 points, 3 sections) and 3 variants: a smoke "
                        "test of the report, under a minute")
    p.add_argument("--out", default="freqid_ablation", metavar="DIR",
                   help="report folder to create (default ./freqid_ablation; "
                        "scripts/ablation.py writes results/ablation)")
    p.add_argument("--force", action="store_true",
                   help="replace an existing report folder (after the new one is complete)")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    # the command recorded in report.md when another entry point (scripts/ablation.py)
    # runs this command
    p.add_argument("--report-command", help=argparse.SUPPRESS)
    return p


def run_cli(args, command):
    """Run ``freqid ablation``; print the conclusions; return 0.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed ``freqid ablation`` arguments (``examples``, ``quick``, ``out``,
        ``force``, ``quiet``, ``report_command``).
    command : str
        The command line, written as the first line of ``report.md`` (unless
        ``--report-command`` names another).
    """
    from ..studies import ablation, ablation_report

    check_out_dir(args.out, args.force)              # before the (long) study
    names = args.examples or (list(ablation.QUICK["examples"]) if args.quick
                              else list(EXAMPLES))
    path, summary = ablation_report.write_ablation_report(
        {n: EXAMPLES[n] for n in names}, args.out, command=args.report_command or command,
        quick=args.quick, force=args.force, progress=not args.quiet)
    for line in summary["conclusions"]:
        print(f"- {line}")
    print(f"total time {summary['total_wall_time']:.1f} s")
    print(f"report: {path}")
    return 0

"""The ``freqid reproduce`` command: the thesis's Table 4.1 and figures (layer 10).

::

    freqid reproduce [--examples LIST] [--quick] [--out DIR] [--force] [--progress|--quiet]

The study is :mod:`freqid_casadi.studies.reproduce_report` (public API only); this module
parses the options, runs it and prints each example's max relative errors.
"""

import argparse
import os
import sys

from .common import _progress
from ..report.formatting import number

__all__ = ["add_cli", "run_cli"]


def add_cli(sub):
    """Add the ``reproduce`` subparser to ``sub`` (the ``freqid`` subparsers); return it.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``freqid`` command's subparsers.
    """
    from ..studies.reproduce import EXAMPLE_NAMES

    p = sub.add_parser(
        "reproduce", help="reproduce the thesis's Table 4.1 and figures 4.1-4.21",
        description="Fit the thesis's examples with our method and the baselines and write "
                    "a report folder (report.md, report.json, figures).")
    p.add_argument("--out", default="freqid_thesis", metavar="DIR",
                   help="report folder to create (default ./freqid_thesis, must not exist "
                        "unless --force; scripts/reproduce_thesis.py writes results/thesis)")
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


def run_cli(args, command):
    """Run ``freqid reproduce``; print the max relative errors and the folder; return 0.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed ``freqid reproduce`` arguments.
    command : str
        The command line, written as the first line of the report.
    """
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

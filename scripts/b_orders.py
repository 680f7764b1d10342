"""Example B (clamped-free beam) against order: where is the thesis's 0.0027 reached?

Usage::

    python scripts/b_orders.py [--sections 9,12,14,16] [--out results/b_orders]

Runs ``freqid sweep example:B --orders <2 x sections> --target 0.0027 --start sequential
--out <out> --force``: G_B (500 points, no integrator, with delay) at each number of
sections with the default method (IPOPT, sequential start), written to ``<out>/sweep.md``
(first line: the command), ``sweep.csv``, ``sweep.json`` and ``sweep.png``, with the max and
RMS relative error, the error on a 10x denser grid, delay and time per order, and the
smallest order whose max relative error is <= 0.0027 (the thesis's value at order 18).
"""

import argparse
import sys

from freqid_casadi.cli import app as cli
from freqid_casadi.systems.examples import EXAMPLES


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sections", default="9,12,14,16")
    ap.add_argument("--out", default="results/b_orders")
    args = ap.parse_args(argv)
    orders = ",".join(str(2 * int(n)) for n in args.sections.split(","))
    return cli.main(["sweep", "example:B", "--orders", orders, "--target",
                     f"{EXAMPLES['B'].thesis.max_rel_error:g}", "--start", "sequential",
                     "--out", args.out, "--force"])


if __name__ == "__main__":
    sys.exit(main())

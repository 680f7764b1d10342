"""Regenerate the example reports under results/examples/ with the CLI.

Usage::

    python scripts/examples.py [--examples A,B,C,fractional]

Runs ``freqid example X --out results/examples/X --force`` for each example, so every
report names the command that made it on its first line; for B also with the minimax
polish (``--objective minimax``, results/examples/B-minimax: issue 5's <= 0.25 at order
18).
"""

import argparse
import os
import sys

from freqid_casadi.cli import main as freqid


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--examples", default="A,B,C,fractional")
    args = ap.parse_args(argv)
    os.makedirs("results/examples", exist_ok=True)
    status = 0
    for name in args.examples.split(","):
        rc = freqid(["example", name, "--out", f"results/examples/{name}", "--force"])
        status = status or rc
        if name == "B":
            rc = freqid(["example", "B", "--objective", "minimax", "--out",
                         "results/examples/B-minimax", "--force"])
            status = status or rc
    return status


if __name__ == "__main__":
    sys.exit(main())

"""Reproduce the thesis's Table 4.1 and figures 4.1-4.21 into ``results/thesis/``.

Usage::

    python scripts/reproduce_thesis.py [--out results/thesis] [--force] [--quick]
                                       [--examples A,B,C,fractional,moheimani]

A thin wrapper around :func:`freqid_casadi.reproduce.main` (also ``freqid reproduce``).
The first line of ``report.md`` names this command.
"""

import sys

from freqid_casadi.reproduce import main

if __name__ == "__main__":
    sys.exit(main(prog="scripts/reproduce_thesis.py"))

"""Ablation study: IPOPT with bounds vs the thesis's barrier-LM, and IPOPT's options.

Usage::

    python scripts/ablation.py [--examples A,B,C,fractional] [--quick]
                               [--out results/ablation] [--force] [--quiet]

The same as ``freqid ablation [same args]`` (:mod:`freqid_casadi.studies.ablation_report`): writes
``<out>/report.md`` (first line: this command), ``<out>/ablation.json`` and PNG figures, and
prints one progress line per variant to stderr. Exit codes as ``freqid``: 0 on success,
2 on a usage or option error, 130 when interrupted.
"""

import shlex
import sys

from freqid_casadi.cli import app as cli


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    command = " ".join(["python", "scripts/ablation.py"] + [shlex.quote(a) for a in argv])
    out = [] if any(a == "--out" or a.startswith("--out=") for a in argv) else \
        ["--out", "results/ablation"]                  # the script writes results/; freqid, ./
    return cli.main(["ablation", *argv, *out, "--report-command", command])


if __name__ == "__main__":
    sys.exit(main())

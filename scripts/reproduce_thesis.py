"""Reproduce the thesis's Table 4.1 and figures 4.1-4.21 into ``results/thesis/``.

Usage::

    python scripts/reproduce_thesis.py [--out results/thesis] [--force] [--quick]
                                       [--examples A,B,C,fractional,moheimani] [--quiet]

The same as ``freqid reproduce [same args]`` (:mod:`freqid_casadi.studies.reproduce_report`),
with progress logged to stderr unless ``--quiet``. The first line of ``report.md`` names
this command. Exit codes as ``freqid``: 0 on success, 2 on a usage or option error, 130
when interrupted.
"""

import shlex
import sys

from freqid_casadi.cli import app as cli


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    command = " ".join(["python", "scripts/reproduce_thesis.py"]
                       + [shlex.quote(a) for a in argv])
    progress = [] if "--quiet" in argv or "--progress" in argv else ["--progress"]
    out = [] if any(a == "--out" or a.startswith("--out=") for a in argv) else \
        ["--out", "results/thesis"]                  # the script writes results/; freqid, ./
    return cli.main(["reproduce", *argv, *out, *progress, "--report-command", command])


if __name__ == "__main__":
    sys.exit(main())

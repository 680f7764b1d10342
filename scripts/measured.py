"""Measured data end to end: the actuator chirp test from its raw records and the DaISy
robot arm, fitted at several orders beside scikit-rf's vector fitting and scipy's AAA.

Usage::

    python scripts/measured.py [--out results/measured] [--force]

Writes ``--out`` atomically (:func:`freqid_casadi.studies.measured_report.write_measured_report`):
``report.md`` (first line: this command), ``report.json`` and the figures. Needs the
``[peers]`` extra (scikit-rf) for the vector-fitting peer; without it that row says so.
"""

import argparse
import os
import shlex
import sys

from freqid_casadi.errors import FreqidError
from freqid_casadi.studies.measured_report import write_measured_report


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join("results", "measured"))
    ap.add_argument("--force", action="store_true")
    args = ap.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    command = " ".join(["python scripts/measured.py"] + [shlex.quote(a) for a in argv])
    try:
        write_measured_report(args.out, command=command, force=args.force,
                              progress=lambda line: print(line, file=sys.stderr))
    except (FreqidError, OSError) as exc:
        sys.stderr.write(f"error: {' '.join(str(exc).split())}\n")
        return 2
    print(f"report: {os.path.join(args.out, 'report.md')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

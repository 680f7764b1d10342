"""The DaISy flexible robot arm (data set 96-009): FRF estimate, fits against order, weight.

Usage::

    python scripts/robot_arm.py [--orders 1,2,3,4,5] [--out results/robot_arm] [--force]

Runs the study :mod:`freqid_casadi.studies.robot_arm` (the FRF estimate from the periodic
experiment, fits with and without delay at each number of sections, the resolution
safeguard, the chosen order and its uncertainty weight) and writes its report folder
(:func:`freqid_casadi.studies.robot_arm_report.write_robot_arm_report`): ``report.md``
(first line: this command), ``report.json``, ``frf.csv`` and the figures.

Data: B. De Moor et al., DaISy: Database for the Identification of Systems, data set 96-009.
"""

import argparse
import os
import shlex
import sys

from freqid_casadi.errors import FreqidError
from freqid_casadi.report.formatting import number
from freqid_casadi.studies.robot_arm_report import write_robot_arm_report


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--orders", default="1,2,3,4,5", help="numbers of sections to fit")
    ap.add_argument("--out", default=os.path.join("results", "robot_arm"))
    ap.add_argument("--force", action="store_true")
    args = ap.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    command = " ".join(["python scripts/robot_arm.py"] + [shlex.quote(a) for a in argv])
    orders = [int(s) for s in args.orders.split(",")]
    try:
        s = write_robot_arm_report(args.out, command=command, orders=orders, force=args.force,
                                   progress=lambda line: print(line, file=sys.stderr))
    except (FreqidError, OSError) as exc:
        sys.stderr.write(f"error: {' '.join(str(exc).split())}\n")
        return 2
    p = s["chosen"]
    print(f"chosen: {p['n_sections']} sections ({p['n_sections_kept']} kept), "
          f"{'with' if p['delay'] else 'no'} delay, "
          f"max rel. error {number(p['max_rel_error'])}, RMS {number(p['rms_rel_error'])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

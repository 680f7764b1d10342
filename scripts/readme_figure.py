"""The README's picture: example A's data, its 17-section model and the relative error.

Usage::

    python scripts/readme_figure.py [--out docs/_static/readme_fit.png]

Fits example A (the thesis's free-free beam) at the thesis's order with the sequential
loop and draws |G| of the data and the model over the relative error |(G - G_N)/G_N| in
one small PNG (about 60 kB).
"""

import argparse
import os
import sys


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join("docs", "_static", "readme_fit.png"))
    args = ap.parse_args(sys.argv[1:] if argv is None else argv)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    import freqid_casadi as fc

    data = fc.systems.G_A()
    res = fc.fit(data, n_sections=17, integrator=True, start="sequential")
    w = data.omega
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(6.4, 4.0), dpi=100,
                                   layout="constrained", height_ratios=(2, 1))
    ax1.loglog(w, np.abs(data.response), lw=4, alpha=0.35, label="data: free-free beam G_A")
    ax1.loglog(w, np.abs(res.model.frequency_response(w)), "k--", lw=1,
               label="model: delay, integrator, 17 sections")
    ax1.set_ylabel("|G|")
    ax1.legend(loc="lower left", fontsize=8)
    ax2.loglog(w, res.rel_error, color="C3")
    ax2.set(xlabel="omega (rad/s)", ylabel="|G/G_N - 1|")
    ax2.set_title(f"relative error, max {res.max_rel_error:.1e} (thesis: 0.2549)", fontsize=9)
    for ax in (ax1, ax2):
        ax.grid(True, which="major", alpha=0.4)
    os.makedirs(os.path.dirname(args.out) or ".", exist_ok=True)
    fig.savefig(args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

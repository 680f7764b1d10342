"""
IPOPT with true bounds against the thesis's barrier + Levenberg-Marquardt
=========================================================================

The package's main path solves each stage as an NLP with bounds ``beta >= 0`` by IPOPT;
the thesis solved it by a log-barrier (SUMT) around Levenberg-Marquardt, kept here as
``method="barrier-lm"``. The same main loop, the same data (example A), a few orders.
The full ablation (every option one at a time) is ``freqid ablation``
(``results/ablation``).
"""

import freqid_casadi as fc
from freqid_casadi import plots

data = fc.systems.G_A()
rows, last = [], {}
for n in (4, 8):
    for method in ("ipopt", "barrier-lm"):
        res = fc.fit(data, n_sections=n, integrator=True, method=method, start="sequential")
        rows.append((n, method, res.max_rel_error, res.nit, res.wall_time))
        last[method] = res

print(f"{'sections':>8s} {'method':>11s} {'max rel. err':>12s} {'iterations':>10s} "
      f"{'time (s)':>8s}")
for n, method, err, nit, t in rows:
    print(f"{n:8d} {method:>11s} {err:12.3g} {nit:10d} {t:8.2f}")

# %%
# The error curves at 8 sections, and the max error after every stage.
plots.relative_error(list(last.values()), labels=list(last))
plots.stage_errors(last)

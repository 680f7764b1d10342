"""
How the sequential loop builds a model
======================================

The main loop (thesis §3.1.3) adds one section per stage at the frequency of the largest
relative error and re-fits all parameters on the data up to there. ``FitResult.stages``
records every stage; here example A at 8 sections.
"""

import freqid_casadi as fc
from freqid_casadi import plots

res = fc.fit(fc.systems.G_A(), n_sections=8, integrator=True, start="sequential")
print(f"{'stage':>5s} {'kind':>12s} {'sections':>8s} {'window':>6s} {'omega_c':>9s} "
      f"{'max rel. err':>12s} {'iterations':>10s}  status")
for st in res.stages:
    print(f"{st.stage:5d} {st.kind.value:>12s} {st.n_sections:8d} {st.window:6d} "
          f"{st.omega_c:9.3g} {st.max_rel_error:12.3g} {st.nit:10d}  {st.status.name}")
print(res.summary())

# %%
# The max relative error after every stage.
plots.stage_errors({"example A, 8 sections": res})

# %%
# Poles and zeros of the final model: all in the closed left half plane.
plots.pole_zero(res.model)

"""
An uncertainty weight for robust design
=======================================

The relative error ``|(G - G_N)/G_N|`` is a multiplicative uncertainty. For an H-infinity or
mu design one needs a stable, minimum-phase weight ``W(s)`` with ``|W(jw)| >= rel. error``
at every frequency: ``uncertainty.weight.fit_uncertainty_weight`` fits one (a low-order
rational function, itself an IPOPT NLP). Here for example A at 6 sections.
"""

import matplotlib.pyplot as plt
import numpy as np

import freqid_casadi as fc
from freqid_casadi.uncertainty.weight import fit_uncertainty_weight

res = fc.fit(fc.systems.G_A(), n_sections=6, integrator=True)
w = fit_uncertainty_weight(res, order=2)
print(w.message)
print("|W| >= rel. error everywhere:", bool(np.all(w.magnitude >= w.rel_error)))
print(f"over-bound: mean {w.overbound.mean_db:.1f} dB, max {w.overbound.max_db:.1f} dB")

# %%
fig, ax = plt.subplots(layout="constrained")
ax.loglog(res.data.omega, res.rel_error, label="relative error of the model")
ax.loglog(w.omega, w.magnitude, label=f"|W(jw)|, order {w.order}")
ax.set(xlabel="omega (rad/s)", ylabel="magnitude", title="multiplicative uncertainty weight")
ax.legend()
ax.grid(True, which="both", alpha=0.3)

"""
One weight over a plant family (``fc.cover``)
=============================================

A production line gives several FRFs of one plant: the units differ a little in stiffness
and damping. A robust design wants one nominal model and one multiplicative weight
``W(s)`` with ``|W(jw)| >= max_i |G_i(jw) / G_N(jw) - 1|`` at every measured point of
every unit (MATLAB's ``ucover``). ``fc.cover`` fits the lowest-order stable,
minimum-phase ``W`` within a stated factor of that envelope; the units may be measured on
different grids. Here six units of a three-mode plant with a 12 ms delay: frequencies
spread by +-12 %, dampings by +-30 %, 2 % noise, and the nominal fitted to the first unit.
"""

import matplotlib.pyplot as plt
import numpy as np

import freqid_casadi as fc

WN, ZETA, RES, DELAY = np.array([3.0, 11.0, 29.0]), np.array([0.04, 0.03, 0.02]), \
    np.array([1.0, 0.35, 0.15]), 0.012
rng = np.random.default_rng(7)
units = []
for i in range(6):
    w = np.sort(np.exp(rng.uniform(np.log(0.3), np.log(100.0), int(rng.integers(120, 200)))))
    wn = WN * (1 + rng.uniform(-0.12, 0.12, 3))
    zeta = ZETA * (1 + rng.uniform(-0.3, 0.3, 3))
    s = 1j * w
    g = np.exp(-DELAY * s) * sum(r * a * a / (s * s + 2 * z * a * s + a * a)
                                 for a, z, r in zip(wn, zeta, RES))
    g = g * (1 + 0.02 * (rng.standard_normal(w.size) + 1j * rng.standard_normal(w.size)))
    units.append(fc.FrequencyData(w, g, name=f"unit {i}"))

nominal = fc.fit(units[0], n_sections=3)
cov = fc.cover(nominal, units, tightness=3.0)   # |W| within 3x of the envelope (median)
print(nominal.message)
print(cov.message)
print(f"W of order {cov.order}; covers every point of every unit: {cov.covers()}")

# %%
# The envelope of the units' relative errors and the weight above it.
fig, ax = plt.subplots(layout="constrained")
for w, e, name in zip(cov.member_omegas, cov.member_errors, cov.member_names):
    ax.loglog(w, e, lw=0.8, alpha=0.6, label=name)
ax.loglog(cov.omega, cov.envelope, "k", lw=1.5, label="envelope")
ax.loglog(cov.omega, np.abs(cov.weight_model.frequency_response(cov.omega)), "r", lw=2,
          label=f"|W(jw)|, order {cov.order}")
ax.set(xlabel="omega (rad/s)", ylabel="relative error",
       title="one multiplicative weight over six units")
ax.legend(fontsize="small", ncol=2)
ax.grid(True, which="both", alpha=0.3)

"""
The first fit: a free-free beam
===============================

The thesis's example A: the velocity of a free-free Euler-Bernoulli beam under a force,
with an integrator and a 10 ms delay, sampled at 500 points from 0.01 to 1000 rad/s. We fit
17 second-order sections (order 34 of the rational part, the thesis's order) with the
thesis's sequential loop, and read the result.
"""

import freqid_casadi as fc
from freqid_casadi import plots

data = fc.systems.G_A()                     # FrequencyData: omega (rad/s), complex response
print(data.omega.shape, data.omega[0], data.omega[-1])

res = fc.fit(data, n_sections=17, integrator=True, start="sequential")
print(res.summary())

# %%
# ``success`` is True only when the final model is at a local optimum within tolerance
# (the scale-free stationarity test after every IPOPT iteration); ``message`` says why.
print(res.success)
print(res.message)
print("max |(G - G_N)/G_N| =", f"{res.max_rel_error:.3g}", " delay =", f"{res.model.delay:.6f} s")

# %%
# The model: stable and minimum phase by construction (every parameter beta >= 0).
model = res.model
print(model.order, model.is_stable(), model.is_minimum_phase())
print("slowest poles:", model.poles()[:4])

# %%
# Bode plot of data and model, and the relative error curve, the headline figure of the
# package (a robust-control designer's multiplicative uncertainty).
plots.bode(res)
plots.relative_error(res)

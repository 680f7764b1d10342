"""
Data outside the model class: a right-half-plane zero
=====================================================

The default model is minimum phase. When the data have excess phase that a delay cannot
explain, the fit says so (diagnostic ``non-minimum-phase``), and ``zeros="free"`` fits the
numerators without sign bounds while every pole stays stable.

The data: two lightly damped modes times an all-pass pair with zeros at 0.8 ± 7.96j rad/s.
"""

import numpy as np

import freqid_casadi as fc
from freqid_casadi import plots

omega = np.logspace(-1, 2, 300)                       # rad/s
s = 1j * omega
plant = 30.0 / (s**2 + 0.4 * s + 4.0) * 400.0 / (s**2 + 2.0 * s + 400.0)
allpass = (s**2 - 1.6 * s + 64.0) / (s**2 + 1.6 * s + 64.0)
data = fc.FrequencyData(omega, 0.1 * plant * allpass, name="two modes x all-pass")

mp = fc.fit(data, n_sections=3, delay=False)
print(mp.summary())
for d in mp.diagnostics:
    print(f"[{d.severity}] {d.code}: {d.message[:160]}...")

# %%
# With free zeros: the right-half-plane pair is recovered and the result says the model is
# not minimum phase.
free = fc.fit(data, n_sections=3, delay=False, zeros="free")
print(free.summary())
print("stable:", free.model.is_stable(), " minimum phase:", free.model.is_minimum_phase())
z = free.model.zeros()
print("right-half-plane zeros:", np.round(z[z.real > 0], 4))

# %%
plots.relative_error([mp, free], labels=["minimum phase", 'zeros="free"'])
plots.pole_zero(free.model)

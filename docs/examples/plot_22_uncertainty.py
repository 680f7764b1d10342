"""
What the data determine: parameter uncertainty and bands
========================================================

``FitResult.uncertainty`` is the covariance of the physical parameters (delay, gain, every
factor's natural frequency and damping) from the Jacobian at the optimum, with the noise
variance from the residuals (or from the data's weights). Here a 2-mode system with two
zero pairs, a 5 ms delay and 1 % complex noise (inside the model class).
"""

import numpy as np

import freqid_casadi as fc
from freqid_casadi.plots.uncertainty import bode_band, rel_error_band

omega = np.logspace(0, 2.5, 400)                        # rad/s
s = 1j * omega
true = (np.exp(-0.005 * s)
        * (s**2 + 3.0 * s + 900.0) / 900.0 * 100.0 / (s**2 + 0.5 * s + 100.0)
        * (s**2 + 12.0 * s + 14400.0) / 14400.0 * 2500.0 / (s**2 + 2.0 * s + 2500.0))
rng = np.random.default_rng(3)
noise = 0.01 * (rng.standard_normal(omega.size) + 1j * rng.standard_normal(omega.size))
data = fc.FrequencyData(omega, true * (1 + noise / np.sqrt(2)), name="2 modes, 1 % noise")

res = fc.fit(data, n_sections=2)
unc = res.uncertainty
print(res.summary())
print(f"delay {1e3 * unc.delay:.3f} ms +- {1e3 * unc.delay_std:.3f} ms (true 5 ms);"
      f" noise variance from the {unc.noise_source}")
for m in res.modes():
    print(f"mode {m.omega_n:8.4f} +- {m.omega_n_std:.4f} rad/s, "
          f"zeta {m.zeta:.5f} +- {m.zeta_std:.5f}")

# %%
# The 95 % confidence band of the response and of the relative error.
bode_band(unc, data)
rel_error_band(unc, data)

"""
A modal survey: shared poles and a stabilization diagram
========================================================

Several FRFs of one structure share its poles. ``fc.fit_shared`` fits them with one set of
stable poles and per-channel numerators; ``fc.stabilization`` repeats it over a range of
orders and marks the poles that stay put, as a modal analyst's stabilization diagram.

The data: a 4-degree-of-freedom chain of masses, springs and dampers (our own numbers),
the receptances of the first mass to a force on every mass.
"""

import numpy as np

import freqid_casadi as fc
from freqid_casadi.plots.modal import stabilization_diagram

m = np.array([1.0, 0.8, 1.2, 0.6])                      # kg
k = np.array([4.0e4, 3.0e4, 5.0e4, 2.0e4])              # N/m
c = np.array([8.0, 5.0, 6.0, 4.0])                      # N s/m


def chain(v):
    a = np.diag(v + np.r_[v[1:], 0.0])
    for i in range(v.size - 1):
        a[i, i + 1] = a[i + 1, i] = -v[i + 1]
    return a


M, K, C = np.diag(m), chain(k), chain(c)
omega = np.linspace(20.0, 600.0, 300)                   # rad/s
H = np.array([np.linalg.inv(K - w**2 * M + 1j * w * C)[0] for w in omega])   # (M, 4)
datas = [fc.FrequencyData(omega, H[:, j], name=f"x1/F{j + 1}") for j in range(4)]

lam = np.linalg.eigvals(np.block([[np.zeros((4, 4)), np.eye(4)],
                                  [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]]))
lam = np.sort_complex(lam[lam.imag > 0])
print("true natural frequencies (rad/s):", np.round(np.abs(lam), 3))
print("true damping ratios:             ", np.round(-lam.real / np.abs(lam), 5))

# %%
shared = fc.fit_shared(datas, 4, delay=False, zeros="free")
print("max rel. errors per channel:", np.array2string(shared.max_rel_errors, precision=2))
for mode in shared.modes:
    print(f"omega_n {mode.omega_n:9.3f} rad/s  zeta {mode.zeta:.5f}")

# %%
# The stabilization diagram over the orders 2..12; a pole is selected as a mode when it
# was stable in frequency and damping over the last two orders.
stab = fc.stabilization(datas, orders=range(2, 13, 2), min_stable=2, delay=False, zeros="free")
stabilization_diagram(stab)

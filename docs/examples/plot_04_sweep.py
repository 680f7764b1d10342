"""
A sweep to a target error
=========================

``fitting.sweep.sweep`` fits a range of orders; each next order starts from the previous
model with one more section at its largest error, so the error never grows with the order.
It reports the smallest order that meets a target (``freqid sweep`` on the command line).
"""

import freqid_casadi as fc
from freqid_casadi import plots
from freqid_casadi.fitting.sweep import sweep

data = fc.systems.G_A()
# orders of P_N (2 per second-order section), with the true system for the error between
# the samples (a grid 10 times denser than the data)
result = sweep(data, orders=range(4, 21, 4), target=1e-3, integrator=True,
               truth=lambda w: fc.systems.G_A_at(1j * w))
for row in result.rows:
    print(f"order {row.order:3d}  max {row.max_rel_error:9.3g}  "
          f"dense grid {row.max_rel_error_dense:9.3g}  delay {row.delay:.5f} s  "
          f"converged {row.success}")
print("smallest order with max rel. error <= 1e-3:", result.best_order)

# %%
plots.sweep(result)

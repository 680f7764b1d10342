"""The thesis's Table 4.1, one parametrised row per example (lmfit test_NIST_Strd style).

Each row fits the benchmark system at the thesis's order with the default method (IPOPT,
sequential start) and checks ``ours <= thesis`` on the max relative error over the 500
points, plus the delay. Where ours is worse, the row stays strict and is an xfail whose
reason gives the measured value (SPEC §5).
"""

from dataclasses import dataclass

import numpy as np
import pytest

import freqid_casadi as fc


@dataclass(frozen=True)
class Row:
    example: str
    n_sections: int
    integrator: bool
    thesis_max_rel_error: float
    thesis_delay: float
    true_delay: float          # nan where G has no delay
    delay_tol: float           # how close our delay must be to the true one
    target: float              # the target for our max relative error


ROWS = {
    "A": Row("A", 17, True, 0.2549, 0.0106, 0.01, 5e-4, 5e-3),
    "B": Row("B", 9, False, 0.0027, 0.011, np.nan, np.nan, 0.0027),
    "C": Row("C", 27, True, 5.9884, 0.0261, 0.02625, 2e-3, 0.2),
}

_CACHE = {}


def _fit(name):
    if name not in _CACHE:
        row = ROWS[name]
        data = {"A": fc.systems.G_A, "B": fc.systems.G_B, "C": fc.systems.G_C}[name]()
        _CACHE[name] = fc.fit(data, n_sections=row.n_sections, integrator=row.integrator)
    return _CACHE[name]


B_REASON = ("measured max rel. error 0.331 (RMS 0.064) at 9 sections > thesis 0.0027: "
            "G_B has 12 resonances and 11 antiresonances in the band, an order-18 model "
            "cannot follow them (SPEC §5); the thesis's MATLAB reports the RMS")


@pytest.mark.slow
@pytest.mark.parametrize("name", [
    "A",
    pytest.param("B", marks=pytest.mark.xfail(strict=True, reason=B_REASON)),
    "C",
])
def test_table_4_1_max_relative_error(name):
    row = ROWS[name]
    res = _fit(name)
    print(f"\n{name}: order {res.model.order}: ours {res.max_rel_error:.4g} "
          f"(RMS {res.rms_rel_error:.3g}), thesis {row.thesis_max_rel_error}; "
          f"delay ours {res.model.delay:.6g}, thesis {row.thesis_delay}")
    assert res.model.is_stable() and res.model.is_minimum_phase()
    assert res.max_rel_error <= row.thesis_max_rel_error
    assert res.max_rel_error <= row.target


@pytest.mark.slow
@pytest.mark.parametrize("name", ["A", "C"])
def test_table_4_1_delay(name):
    row = ROWS[name]
    res = _fit(name)
    assert abs(res.model.delay - row.true_delay) <= row.delay_tol


@pytest.mark.slow
def test_example_c_beats_infinite_gain_model():
    """Any max relative error >= 1 is worse than an infinite-gain model (SPEC §5)."""
    assert _fit("C").max_rel_error < 1.0

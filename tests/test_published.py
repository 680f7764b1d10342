"""The thesis's Table 4.1, one parametrised row per example (lmfit test_NIST_Strd style).

Each row fits the benchmark system at the thesis's order with the thesis's own loop (IPOPT,
``start="sequential"``, given explicitly) and checks ``ours <= thesis`` on the max relative
error over the 500 points, and ours within a stated factor of what we measure, so that a
regression cannot hide under the thesis's number; plus the delay. Where ours is worse, the
row stays strict and is an xfail whose reason gives the measured value (SPEC §5).
"""

import pytest

import freqid_casadi as fc
from freqid_casadi.systems.examples import EXAMPLES


#: The test's own tolerances per example (the structure and the thesis's numbers come from
#: the catalogue): how close our delay must be to the true one (s).
DELAY_TOL = {"A": 5e-4, "C": 2e-3}
#: Our max relative error as measured: (an AVX-512 machine's OpenBLAS kernel, the worst
#: over the OpenBLAS kernels, numpy's SIMD levels and rounding-level perturbations of the
#: data on that machine and on an AVX2 machine; results/reproducibility.md). C's curved
#: valley makes it move with rounding: on the AVX2 machine numpy's AVX2 functions send the
#: sequential loop astray and the delay search's rational-start trial brings it to 8.0e-7.
MEASURED = {"A": (4.8e-14, 1.4e-12), "B": (0.331, 0.331), "C": (1.1e-10, 8.0e-7)}
#: How far above the worst measured value a row may land before it counts as a regression.
FACTOR = 10.0

_CACHE = {}


def _fit(name):
    if name not in _CACHE:
        ex = EXAMPLES[name]
        _CACHE[name] = fc.fit(ex.data(), n_sections=ex.n_sections, integrator=ex.integrator,
                              start="sequential")
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
    thesis = EXAMPLES[name].thesis
    res = _fit(name)
    print(f"\n{name}: order {res.model.order}: ours {res.max_rel_error:.4g} "
          f"(RMS {res.rms_rel_error:.3g}), thesis {thesis.max_rel_error}; "
          f"delay ours {res.model.delay:.6g}, thesis {thesis.delay}")
    assert res.model.is_stable() and res.model.is_minimum_phase()
    assert res.max_rel_error <= thesis.max_rel_error
    assert res.max_rel_error <= FACTOR * MEASURED[name][1]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["A", "C"])
def test_table_4_1_delay(name):
    res = _fit(name)
    assert abs(res.model.delay - EXAMPLES[name].true_delay) <= DELAY_TOL[name]


@pytest.mark.slow
def test_example_c_beats_infinite_gain_model():
    """Any max relative error >= 1 is worse than an infinite-gain model (SPEC §5)."""
    assert _fit("C").max_rel_error < 1.0

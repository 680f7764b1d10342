"""Shared plants and fixtures of the test suite.

The plants many test files fit or read are built here once (a newcomer adds a test by
asking for a fixture, not by writing a plant again):

- ``one_section_model``: G(s) = 2 e^{-0.01 s} (s^2 + 2·0.3·5 s + 25) / (s^2 + 2·0.05·3 s + 9)
  (a :class:`~freqid_casadi.RationalDelayModel` with one section and a 10 ms delay).
- ``first_order_response(omega)``: 2 e^{-0.01 j omega} / (1 + j omega / 3).
- ``example_data(name)``: the benchmark systems A, B and C of docs/spec.md §4, 500 points.
- ``densely_sampled(index, n_points)``: corpus case ``index`` (seed 0) resampled at
  ``n_points`` frequencies, its noise seeded by the index (as ``scripts/settle_check.py``).

Figures are closed after every test (after python-control's ``conftest.py::mplcleanup``).
"""

import sys

import numpy as np
import pytest

import freqid_casadi as fc

#: beta of the one-section plant (delay, gain, then a, zeta_n, omega_n, b, zeta_d, omega_d)
ONE_SECTION_BETA = [0.01, 2.0, 1.0, 0.3, 5.0, 1.0, 0.05, 3.0]


def one_section_model():
    """The one-section plant with a 10 ms delay (a fresh RationalDelayModel)."""
    return fc.RationalDelayModel(fc.Structure(1), ONE_SECTION_BETA)


def first_order_response(omega):
    """2 e^{-0.01 j omega} / (1 + j omega / 3): gain, a 10 ms delay and one real pole."""
    omega = np.asarray(omega, dtype=float)
    return 2.0 * np.exp(-0.01j * omega) / (1 + 1j * omega / 3.0)


def densely_sampled(index, n_points):
    """Corpus case ``index`` (seed 0) at ``n_points`` frequencies over its band, its
    relative noise profile interpolated, the noise seeded by the index
    (:meth:`~freqid_casadi.systems.corpus.CorpusCase.resampled`)."""
    c = fc.systems.case(index, 0, max_points=5000)
    return c.resampled(n_points, np.random.default_rng(1000 + index))


@pytest.fixture(name="one_section_model")
def _one_section_model():
    return one_section_model()


@pytest.fixture(scope="session")
def example_data():
    """``example_data("A")``: the benchmark system's FrequencyData (cached per session)."""
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = getattr(fc.systems, f"G_{name}")()
        return cache[name]

    return get


@pytest.fixture
def small_subset(monkeypatch):
    """``small_subset(above, points, watch)``: the thresholds of the subset a fit of many
    points settles its choices on (``core_fits.SETTLE_ABOVE``, ``SETTLE_POINTS``) lowered
    for a test's small data; with ``watch`` (``"settle_on_subset"`` or
    ``"sign_on_subset"``) it returns the list that collects what each call of that
    function returned."""
    from freqid_casadi.fitting import core_fits
    from freqid_casadi.fitting import fit as fit_module

    def lower(above, points, watch=None):
        monkeypatch.setattr(core_fits, "SETTLE_ABOVE", above)
        monkeypatch.setattr(core_fits, "SETTLE_POINTS", points)
        tried = []
        if watch is not None:
            settle = getattr(fit_module, watch)
            monkeypatch.setattr(fit_module, watch,
                                lambda *a: tried.append(settle(*a)) or tried[-1])
        return tried

    return lower


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt = sys.modules.get("matplotlib.pyplot")
    if plt is not None:
        plt.close("all")

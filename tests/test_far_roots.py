"""Roots far above the band moved to infinity, their phase into the delay."""

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.fitting.far_roots import FAR, roots_to_infinity


def _two_modes(points=300):
    # a user's exact analyser file: two modes, the first without zeros, a 2 ms delay
    f = np.linspace(0.5, 30, points)
    s = 2j * np.pi * f
    w1, w2 = 2 * np.pi * 5, 2 * np.pi * 12
    h = (3 * np.exp(-0.002 * s) * w1**2 / (s**2 + 0.04 * w1 * s + w1**2)
         * (0.5 * w2**2 / (s**2 + 0.06 * w2 * s + w2**2) + 0.5))
    return fc.FrequencyData(2 * np.pi * f, h)


def test_roots_to_infinity_keeps_the_response_to_second_order():
    w = np.logspace(0, 2, 200)
    beta = [0.01, 2.0, 1.0, 0.7, 5e4, 1.0, 0.05, 30.0]       # zero pair at 5e4 rad/s
    model = fc.RationalDelayModel(fc.Structure(1, delay=True), beta)
    moved, n = roots_to_infinity(model, w[-1])
    assert n == 1 and moved.sections()[0][0] == 0 and moved.sections()[0][1] == 0
    assert moved.delay == pytest.approx(0.01 - 2 * 0.7 / 5e4, rel=1e-12)
    err = np.max(np.abs(moved.frequency_response(w) / model.frequency_response(w) - 1))
    assert err < 2 * (w[-1] / 5e4) ** 2                       # (omega / wn)^2: 8e-6
    # nothing near the band, or no delay: the model itself
    near = fc.RationalDelayModel(fc.Structure(1, delay=True),
                                 [0.01, 2.0, 1.0, 0.7, 0.9 * FAR * w[-1], 1.0, 0.05, 30.0])
    assert roots_to_infinity(near, w[-1]) == (near, 0)
    no_delay = fc.RationalDelayModel(fc.Structure(1, delay=False), [0.0] + beta[1:])
    assert roots_to_infinity(no_delay, w[-1])[1] == 0


def test_exact_two_mode_data_converge_with_the_sequential_loop():
    data = _two_modes()
    # by default the delay search, whose trials include the rational start for a run of
    # the sequential loop alone, converges first (measured 1.4e-14)
    res = fc.fit(data, n_sections=2, start="sequential")
    assert res.success, res.message
    assert res.max_rel_error < 1e-12
    # the far-roots candidate on its own (the delay search off), from the loop's model:
    # measured 1.35e-8 -> 4.8e-12, at its iteration limit (before the delay search had the
    # rational start, the far roots ran from the search's model and converged)
    res = fc.fit(data, n_sections=2, start="sequential",
                 loop=fc.LoopOptions(delay_search=False))
    errors = res.candidate_max_rel_errors
    assert "sequential, far roots" in errors
    assert errors["sequential, far roots"] < 1e-3 * errors["sequential"]
    assert res.max_rel_error < 1e-10
    assert any(r.kind == fc.fitting.stages.StageKind.FAR_ROOTS for r in res.stages)
    # without either: a zero pair drifting above the band against the delay
    off = fc.fit(data, n_sections=2, start="sequential",
                 loop=fc.LoopOptions(far_roots=False, delay_search=False))
    assert not off.success and off.max_rel_error > 1e-10

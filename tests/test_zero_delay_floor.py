"""The phase floor of the h = 0 candidate (fitting.candidates.zero_delay_floor): a lower
bound of every delay-free model's max relative error, and the fit skips a candidate the
bound rules out of choose()'s pool without changing what the fit keeps."""

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.fitting import candidates
from freqid_casadi.fitting.candidates import NEAR, zero_delay_floor

W = np.logspace(-1, 1, 150)
S = 1j * W


def _delayed(h, noise=0.0, seed=0):
    """Two lightly damped modes and an antiresonance, delayed by h s (lag 10 h rad at the
    top of the band), with complex relative noise."""
    g = (S * S + 0.1 * S + 2.0) / ((S * S + 0.2 * S + 1.0) * (S * S + 0.3 * S + 9.0))
    g = g * np.exp(-h * S)
    rng = np.random.default_rng(seed)
    g = g * (1 + noise * (rng.standard_normal(W.size) + 1j * rng.standard_normal(W.size)))
    return fc.FrequencyData(W, g)


def _structure(n, **kw):
    return fc.Structure(n, delay=False, **kw)


def test_no_delay_and_a_short_one_give_no_floor():
    assert zero_delay_floor(_delayed(0.0), _structure(2)) == 0.0
    assert zero_delay_floor(_delayed(0.2), _structure(2)) == 0.0      # 2 rad of lag
    # the lag the sections can follow grows with them: 25 rad beat 1 section, not 8
    assert zero_delay_floor(_delayed(2.5), _structure(1)) > 0.5
    assert zero_delay_floor(_delayed(2.5), _structure(8)) == 0.0


def test_the_floor_rises_with_the_delay_to_one():
    # measured 0.23, 0.65, 0.93, 1 (not monotone in every step: a turn of the model's
    # phase skips whole steps of the data's)
    floors = [zero_delay_floor(_delayed(h), _structure(3)) for h in (0.8, 1.2, 1.5, 3.0)]
    assert floors == sorted(floors) and 0.1 < floors[0] < 0.5
    assert floors[-1] == 1.0


def test_a_lead_is_the_mirror_of_a_lag():
    lag = _delayed(1.2)
    lead = fc.FrequencyData(W, np.conj(lag.response))
    assert zero_delay_floor(lead, _structure(3)) == zero_delay_floor(lag, _structure(3))
    assert 0.3 < zero_delay_floor(lag, _structure(3)) < 1.0          # measured 0.645


@pytest.mark.parametrize("kw, h", [({}, 0.8), ({}, 1.2), ({"zeros": "free"}, 1.2),
                                   ({"zeros": "free"}, 1.3), ({"basis": "first-order"}, 0.8),
                                   ({"basis": "first-order"}, 1.2)])
def test_no_fitted_delay_free_model_beats_the_floor(kw, h):
    # the bound holds for the best model the package finds without a delay (and for any
    # other); free zeros may lag too (a lower floor), first-order sections half as much
    data = _delayed(h, noise=0.01)
    n = 4 if kw.get("basis") == "first-order" else 2
    floor = zero_delay_floor(data, _structure(n, **kw))
    res = fc.fit(data, n_sections=n, delay=False, integrator=False, **kw)
    assert floor > 0.4                                      # measured 0.42-0.95
    assert res.max_rel_error >= floor


def test_noisy_phase_only_lowers_the_floor():
    # noise makes large phase steps, which a model's phase turn may skip: the floor
    # falls but stays a bound
    clean = zero_delay_floor(_delayed(0.8), _structure(2))
    noisy = zero_delay_floor(_delayed(0.8, noise=0.3), _structure(2))
    assert 0 < noisy < clean                                # measured 0.68 and 0.85


def _fit(monkeypatch, data, n, *, floor_on):
    with monkeypatch.context() as m:
        if not floor_on:
            m.setattr(candidates, "zero_delay_floor", lambda d, s: 0.0)
        return fc.fit(data, n_sections=n, integrator=False, gain_sign="positive")


@pytest.mark.parametrize("weighted", [False, True])
def test_a_skipped_candidate_changes_nothing_the_fit_keeps(monkeypatch, weighted):
    # one section for a mode and a pole-zero pair, 15 rad of delay: the fits miss the
    # pair (max error 0.66, measured), so the screen does not abandon the h = 0 polish
    # (it ends at 1.27); the floor (1) rules it out
    g = (S * S + 0.3 * S + 9.0) / (S * S + 0.6 * S + 10.0) / (S * S + 0.2 * S + 1.0)
    noise = np.random.default_rng(0).standard_normal((2, W.size))
    data = fc.FrequencyData(W, g * np.exp(-1.5 * S) * (1 + 0.01 * (noise[0] + 1j * noise[1])))
    low = high = 1.0            # the range of sqrt(w / mean(w)): the weighted ranks'
    if weighted:
        w = np.linspace(0.8, 1.2, W.size)
        data = fc.FrequencyData(W, data.response, None, w)
        low, high = np.sqrt(w.min() / w.mean()), np.sqrt(w.max() / w.mean())
    with_floor = _fit(monkeypatch, data, 1, floor_on=True)
    without = _fit(monkeypatch, data, 1, floor_on=False)
    zero = {k: v for k, v in without.candidate_max_rel_errors.items() if "h=0" in k}
    assert zero, "the h = 0 candidates ran without the floor"
    best = min(with_floor.candidate_max_rel_errors.values())
    floor = zero_delay_floor(data, _structure(1))
    assert low * floor > NEAR * high * best         # the ranks of the skipped and the best
    assert all(v >= floor for v in zero.values())
    assert not any("h=0" in k for k in with_floor.candidate_max_rel_errors)
    assert np.array_equal(with_floor.model.beta, without.model.beta)
    assert with_floor.status == without.status and with_floor.message == without.message
    assert with_floor.candidate_max_rel_errors == {
        k: v for k, v in without.candidate_max_rel_errors.items() if k not in zero}


def test_zero_weights_leave_no_floor_to_rank_by():
    data = _delayed(1.5)
    w = np.ones(W.size)
    w[70] = 0.0
    assert zero_delay_floor(data, _structure(1)) == 1.0
    assert candidates._ranked_floor(fc.FrequencyData(W, data.response, None, w),
                                    _structure(1)) == 0.0

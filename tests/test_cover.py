"""fc.cover: one weight W(s) over a plant family; python-control and scikit-rf in and out."""

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi import DataError, OptionError
from freqid_casadi.core.model import RationalDelayModel, Structure
from freqid_casadi.uncertainty.cover import envelope, envelope_grid, thinned

ct = pytest.importorskip("control")

WN = np.array([3.0, 11.0, 29.0])       # rad/s
ZETA = np.array([0.04, 0.03, 0.02])
RES = np.array([1.0, 0.35, 0.15])
DELAY = 0.012                          # s


def modal(omega, wn, zeta, res, delay):
    """Collocated modal sum sum_k r_k wn_k^2 / (s^2 + 2 zeta_k wn_k s + wn_k^2), delayed."""
    s = 1j * np.asarray(omega, float)
    g = sum(r * w * w / (s * s + 2 * z * w * s + w * w) for w, z, r in zip(wn, zeta, res))
    return np.exp(-delay * s) * g


def modal_model(wn, zeta, res, delay):
    """The same plant as a RationalDelayModel (exact: zeros from the numerator)."""
    dens = [np.array([1.0, 2 * z * w, w * w]) for w, z in zip(wn, zeta)]
    num = np.zeros(1)
    for k, r in enumerate(res):
        term = np.array([r * wn[k] ** 2])
        for j, d in enumerate(dens):
            if j != k:
                term = np.polymul(term, d)
        num = np.polyadd(num, term)
    zeros = np.roots(num)
    zeros = sorted([z for z in zeros if z.imag > 0], key=abs)
    beta = [delay, 0.0]
    dc = float(np.sum(res))
    prod = 1.0
    for k, (w, z) in enumerate(zip(wn, zeta)):
        if k < len(zeros):
            wz = abs(zeros[k])
            beta += [1.0, -zeros[k].real / wz, wz, 1.0, z, w]
            prod *= wz * wz / (w * w)
        else:                          # relative degree 2: a constant numerator
            beta += [0.0, 0.0, 1.0, 1.0, z, w]
            prod *= 1.0 / (w * w)
    beta[1] = dc / prod
    return RationalDelayModel(Structure(len(wn), False, True), np.array(beta))


def family(n_members=8, seed=7):
    """Members on their own random grids: frequencies +-12 %, dampings +-30 %, 2 % noise."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n_members):
        n = int(rng.integers(120, 200))
        w = np.sort(np.exp(rng.uniform(np.log(0.3), np.log(100.0), n)))
        wn = WN * (1 + rng.uniform(-0.12, 0.12, WN.size))
        zeta = ZETA * (1 + rng.uniform(-0.3, 0.3, ZETA.size))
        g = modal(w, wn, zeta, RES, DELAY)
        g = g * (1 + 0.02 * (rng.standard_normal(n) + 1j * rng.standard_normal(n)))
        out.append(fc.FrequencyData(w, g, name=f"unit {i}"))
    return out


NOMINAL = modal_model(WN, ZETA, RES, DELAY)
MEMBERS = family()


def test_modal_model_is_the_modal_sum():
    w = np.logspace(-1, 2, 50)
    rel = np.abs(NOMINAL.frequency_response(w) / modal(w, WN, ZETA, RES, DELAY) - 1)
    assert np.max(rel) < 1e-10


@pytest.fixture(scope="module")
def covered():
    return fc.cover(NOMINAL, MEMBERS)


def test_cover_bounds_every_member_at_every_point(covered):
    c = covered
    assert c.covers()
    for d, e in zip(MEMBERS, c.member_errors):
        direct = np.abs(d.response / NOMINAL.frequency_response(d.omega) - 1)
        np.testing.assert_array_equal(e, direct)
        assert np.all(np.abs(c.weight_model.frequency_response(d.omega)) >= e)
        assert np.all(np.abs(c.weight.frequency_response(d.omega)) >= e)
        tf = np.asarray(ct.frequency_response(c.weight_tf, d.omega).magnitude).ravel()
        assert np.all(tf >= e * (1 - 1e-9))


def test_cover_weight_is_stable_minimum_phase_and_tight(covered):
    c = covered
    assert c.weight.is_stable() and c.weight.is_minimum_phase()
    assert np.all(np.real(ct.poles(c.weight_tf)) < 0)
    assert np.all(np.real(ct.zeros(c.weight_tf)) < 0)
    assert c.weight_model.is_stable(strict=True) and c.weight_model.delay == 0
    # measured: order 6, median 1.89 (the default tightness 2 stops the ladder there)
    assert c.success and c.median_ratio <= c.tightness == 2.0
    assert c.median_ratio <= 3.0
    assert 1 <= c.order <= 8 and c.order == c.weight.order
    assert c.median_ratios[c.order] == pytest.approx(c.median_ratio, rel=1e-9)
    lower = [r for n, r in c.median_ratios.items() if n < c.order]
    assert all(r > c.tightness for r in lower)        # the lowest order that is tight enough


def test_envelope_on_different_grids_is_exact_at_each_members_points(covered):
    c = covered
    env_at = dict(zip(c.omega.tolist(), c.envelope.tolist()))
    for w, e in zip(c.member_omegas, c.member_errors):
        assert all(env_at[x] >= y for x, y in zip(w.tolist(), e.tolist()))
    # between two points a member counts by log-log interpolation, outside its band not
    w1, e1 = np.array([1.0, 4.0]), np.array([0.1, 0.4])
    w2, e2 = np.array([2.0, 8.0]), np.array([0.05, 0.05])
    grid = envelope_grid([w1, w2])
    np.testing.assert_allclose(grid, [1, np.sqrt(2), 2, np.sqrt(8), 4, np.sqrt(32), 8])
    env = envelope(grid, [w1, w2], [e1, e2])
    np.testing.assert_allclose(env, [0.1, 0.1 * np.sqrt(2), 0.2, 0.1 * np.sqrt(8), 0.4,
                                     0.05, 0.05])
    idx = thinned(np.arange(1.0, 101.0), np.ones(100), 10)
    assert 9 <= idx.size <= 11


def test_cover_with_pade_covers_the_rational_nominal():
    c = fc.cover(NOMINAL, MEMBERS[:4], order=4, pade_order=2)
    sys = c.nominal_control()
    assert sys.delay == 0 and sys.nstates == 2 * NOMINAL.n_sections + 2
    for d, e in zip(MEMBERS[:4], c.member_errors):
        g = np.asarray(ct.frequency_response(sys, d.omega).complex).ravel()
        direct = np.abs(d.response / g - 1)
        np.testing.assert_allclose(e, direct, rtol=1e-9, atol=1e-12)
        assert np.all(np.abs(c.frequency_response(d.omega)) >= e)
    pade = np.abs(np.exp(-1j * c.omega * DELAY) - 1)     # a first guess is far larger
    assert np.all(c.pade_error <= pade + 1e-12) and c.pade_error.max() > 0
    assert c.order == 4


def test_to_control_delay_pade_is_rational():
    a = NOMINAL.to_control()
    assert a.delay == DELAY and a.nstates == 6
    b = NOMINAL.to_control(delay="pade", pade_order=3)
    assert b.delay == 0 and b.nstates == 9
    w = np.array([0.5, 5.0])
    g = np.asarray(ct.frequency_response(b, w).complex).ravel()
    assert np.max(np.abs(g / NOMINAL.frequency_response(w) - 1)) < 1e-6
    assert NOMINAL.to_control(delay="attribute").delay == DELAY
    with pytest.raises(OptionError, match="needs pade_order"):
        NOMINAL.to_control(delay="pade")
    with pytest.raises(OptionError, match="delay must be one of"):
        NOMINAL.to_control(delay="exact")
    with pytest.raises(OptionError, match="drop pade_order"):
        NOMINAL.to_control(delay="attribute", pade_order=2)


def test_frd_in_and_out():
    sys = ct.tf([1.0], [1.0, 0.4, 1.0])
    w = np.logspace(-1, 1.3, 80)
    frd = ct.frd(sys, w)
    res = fc.fit(frd, n_sections=1, delay=False)
    assert res.max_rel_error < 1e-6 and res.data.n_points == 80
    back = res.data.to_frd()
    np.testing.assert_array_equal(back.omega, w)
    np.testing.assert_array_equal(np.asarray(back.frdata).ravel(), res.data.response)
    shared = fc.fit_shared([frd, ct.frd(2 * sys, w)], 1, delay=False)
    assert shared.max_rel_errors.shape == (2,)
    c = fc.cover(res, [frd, ct.frd(sys * ct.tf([1], [0.02, 1]), w)], order=2)
    assert c.covers() and c.member_names == ("member 0", "member 1")
    with pytest.raises(DataError, match="SISO"):
        fc.fit(ct.frd(ct.ss(np.eye(2) * -1, np.eye(2), np.eye(2), 0), w), n_sections=1)


def test_skrf_network_one_port():
    skrf = pytest.importorskip("skrf")
    f = np.linspace(1e6, 1e8, 60)
    s11 = (1 + 0.5j * f / 1e7) / (1 + 1j * f / 3e7)
    net = skrf.Network(frequency=skrf.Frequency.from_f(f, unit="hz"),
                       s=s11.reshape(-1, 1, 1), name="dut")
    data = fc.core.data.as_frequency_data(net)
    np.testing.assert_allclose(data.omega, 2 * np.pi * f)
    assert data.name == "dut"
    res = fc.fit(net, n_sections=1, delay=False)
    assert res.data.name == "dut"
    two = skrf.Network(frequency=skrf.Frequency.from_f(f, unit="hz"),
                       s=np.ones((60, 2, 2)) * 0.1)
    with pytest.raises(DataError, match="one-port"):
        fc.fit(two, n_sections=1)


@pytest.mark.parametrize("kwargs, err, match", [
    ({"order": -1}, OptionError, "order must be"),
    ({"margin": -0.1}, OptionError, "margin must be"),
    ({"tightness": 0.5}, OptionError, "tightness must be"),
    ({"pade_order": -2}, OptionError, "pade_order"),
    ({"max_points": 3}, OptionError, "max_points"),
])
def test_cover_bad_options(kwargs, err, match):
    with pytest.raises(err, match=match):
        fc.cover(NOMINAL, MEMBERS[:1], **kwargs)


def test_cover_bad_inputs():
    with pytest.raises(DataError, match="model must be"):
        fc.cover("nominal", MEMBERS)
    with pytest.raises(DataError, match=r"datas\[1\] must be one of"):
        fc.cover(NOMINAL, [MEMBERS[0], np.ones(3)])
    with pytest.raises(DataError, match="empty"):
        fc.cover(NOMINAL, [])


def test_to_control_is_balanced_with_a_far_zero():
    # a section whose zeros are at 1e4 and 1e11 rad/s (the relative degree a fit stands in
    # for): unbalanced, A had entries 1e7 apart and the response was off by 4e-4
    beta = np.array([0.0, 6.4e-14, 1.0, 2504.0, 5.3e7, 1.0, 0.01, 38.0,
                     1.0, 0.02, 4.0, 1.0, 0.02, 15.0])
    model = RationalDelayModel(Structure(2, False, False), beta)
    sys = model.to_control()
    w = np.array([1.0, 4.0, 40.0])
    g = np.asarray(ct.frequency_response(sys, w).complex).ravel()
    # measured 4.3e-10 near the mode at 38 rad/s (zeta 0.01)
    np.testing.assert_allclose(g, model.frequency_response(w), rtol=1e-8)
    assert np.linalg.norm(sys.A) < 1e4
    np.testing.assert_allclose(np.sort_complex(ct.poles(sys)),
                               np.sort_complex(model.poles()), rtol=1e-10)


def test_an_envelope_of_noise_says_no_weight_follows_it():
    # one member: the nominal times 2 % white noise. No order follows an envelope that
    # jumps from point to point (measured median ratios 3.8 at order 0 down to 2.6): the
    # message had asked only for a larger max_order
    rng = np.random.default_rng(3)
    w = np.geomspace(0.3, 100.0, 160)
    g = modal(w, WN, ZETA, RES, DELAY) * (
        1 + 0.02 * (rng.standard_normal(w.size) + 1j * rng.standard_normal(w.size)))
    cov = fc.cover(NOMINAL, [fc.FrequencyData(w, g)], max_order=2)
    assert not cov.success and cov.covers()
    assert cov.message.startswith("no order up to 2 reaches median |W|/envelope <= 2 (median "
                                  "ratio by order 0: ")
    assert "An envelope that jumps from point to point" in cov.message
    assert "order=0: a constant weight, ratio " in cov.message

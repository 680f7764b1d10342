"""Tests of fit_shared: derivatives and the block-arrowhead Hessian, sdypy-EMA's acceptance
system, Moheimani's beam seen by several sensors, export and input errors."""

import warnings

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.modal._nlp import SharedProblem
from freqid_casadi.errors import DataError, OptionError
from freqid_casadi.core.model import RationalDelayModel
from freqid_casadi.modal.shared import SharedFitResult, fit_shared
from freqid_casadi.systems import moheimani_modes


def _random_problem(delay, integrator=True, seed=0, local=False):
    rng = np.random.default_rng(seed)
    c, m = 3, 30
    w = np.linspace(1.0, 10.0, m)
    phi = rng.normal(size=(c, m)) + 1j * rng.normal(size=(c, m))
    wl = [[3.0, 8.0], [4.0, 9.0], [6.0, 12.0]] if local else None   # 2 sections per channel
    prob = SharedProblem(w, phi, rng.uniform(0.5, 1.0, (c, m)), np.ones(c), [2.0, 5.0],
                         integrator, delay, [True, False, True], 0.1, wl)
    z = rng.uniform(0.1, 1.0, prob.n_vars)
    z[prob.n_shared] = -0.3                       # a negative gain variable (free channel)
    return prob, z


@pytest.mark.parametrize("local", [False, True])
@pytest.mark.parametrize("delay", ["per-channel", "shared", False])
def test_gradient_and_hessian_match_finite_differences(delay, local):
    prob, z = _random_problem(delay, local=local)
    cost, grad = prob.gradient(z)
    assert cost == pytest.approx(prob.cost(z), rel=1e-14)
    eye = np.eye(prob.n_vars)
    eps = 1e-6
    fd = np.array([(prob.cost(z + eps * e) - prob.cost(z - eps * e)) / (2 * eps) for e in eye])
    assert np.max(np.abs(grad - fd)) < 1e-7 * np.max(np.abs(grad))
    fdh = np.array([(prob.gradient(z + eps * e)[1] - prob.gradient(z - eps * e)[1]) / (2 * eps)
                    for e in eye])
    h = prob.hessian_dense(z)
    assert np.max(np.abs(h - fdh)) < 1e-7 * np.max(np.abs(h))


@pytest.mark.parametrize("local", [False, True])
@pytest.mark.parametrize("delay", ["per-channel", "shared", False])
def test_casadi_ad_hessian_is_block_arrowhead_and_equals_ours(delay, local):
    import casadi as ca

    prob, z = _random_problem(delay, local=local)
    x = ca.SX.sym("z", prob.n_vars)
    f = prob.casadi_cost(x)
    hess = ca.hessian(f, x)[0]
    assert float(ca.Function("f", [x], [f])(z)) == pytest.approx(prob.cost(z), rel=1e-13)
    ours = prob.hessian_dense(z)
    ad = np.array(ca.Function("h", [x], [hess])(z))
    assert np.max(np.abs(ad - ours)) < 1e-12 * np.max(np.abs(ad))
    # AD's structural pattern == the arrowhead we hand IPOPT: no channel-channel block
    rows, cols, _ = prob.hessian_pattern()
    pattern = np.zeros(ours.shape, bool)
    pattern[rows, cols] = True
    pattern |= pattern.T
    r_ad, c_ad = hess.sparsity().get_triplet()
    ad_pattern = np.zeros(ours.shape, bool)
    ad_pattern[r_ad, c_ad] = True
    assert np.array_equal(ad_pattern, pattern)
    ns, no = prob.n_shared, prob.n_own
    assert not ad_pattern[ns:ns + no, ns + no:].any()          # channel 1 x channels 2, 3
    if local:                  # the channel sections are channel-block variables
        lq = prob.layout()["lq"]
        assert lq.shape == (3, 2, 2) and np.all(lq[0] < ns + no) and np.all(lq[1] >= ns + no)
        lb = prob.bounds()[0]
        assert np.all(lb[lq] == 0) and np.all(lb[prob.layout()["lp"][1]] == 0)
        assert np.all(lb[prob.layout()["lp"][0]] == -np.inf)     # free channel

def test_hessian_nonzeros_grow_linearly_with_channels():
    counts = []
    for c in (4, 8, 16):
        w = np.linspace(1.0, 10.0, 20)
        prob = SharedProblem(w, np.ones((c, 20), complex), np.ones((c, 20)), np.ones(c),
                             [2.0, 5.0, 7.0], False, "per-channel", [False] * c, 0.1)
        counts.append(prob.hessian_pattern()[0].size)
    assert counts[2] - counts[1] == 2 * (counts[1] - counts[0])


# ------------------------------------------------------------------ sdypy-EMA's system
def _chain(values):
    """Stiffness-type matrix of a chain grounded on the left (pyLump boundaries="left")."""
    n = len(values)
    a = np.zeros((n, n))
    for i in range(n):
        a[i, i] += values[i]
        if i + 1 < n:
            a[i, i] += values[i + 1]
            a[i, i + 1] -= values[i + 1]
            a[i + 1, i] -= values[i + 1]
    return a


def ema_system():
    """sdypy-EMA's acceptance system (tests/test_tools/generate_synth_frf.py): 5-DOF chain,
    masses/stiffnesses/dampings drawn after ``np.random.seed(6020)``, 5000 linear points,
    first row of the receptance matrix. Returns (datas, f_true (Hz), zeta_true)."""
    state = np.random.get_state()
    try:
        np.random.seed(6020)
        m = np.random.uniform(0.1, 1, 5)
        k = np.random.uniform(500e3, 1e6, 5)
        c = np.random.uniform(10, 100, 5)
    finally:
        np.random.set_state(state)
    M, K, C = np.diag(m), _chain(k), _chain(c)
    lam = np.linalg.eigvals(np.block([[np.zeros((5, 5)), np.eye(5)],
                                      [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]]))
    lam = np.sort_complex(lam[lam.imag > 0])
    lam = lam[np.argsort(np.abs(lam))]
    f_true, zeta_true = np.abs(lam) / (2 * np.pi), -lam.real / np.abs(lam)
    f_min = np.round(f_true[0] * 0.25 / 10) * 10
    f_max = np.round(f_true[-1] * 5.0 / 100) * 100
    omega = 2 * np.pi * np.linspace(f_min, f_max, 5000)
    row = np.array([np.linalg.inv(K - w * w * M + 1j * w * C)[0] for w in omega]).T
    return [fc.FrequencyData(omega, row[j], f"H1{j + 1}") for j in range(5)], f_true, zeta_true


def test_ema_system_matches_pylump():
    lumped = pytest.importorskip("pyLump")
    rng = np.random.RandomState(6020)          # the same stream as np.random.seed(6020)
    m = rng.uniform(0.1, 1, 5)
    k = rng.uniform(500e3, 1e6, 5)
    c = rng.uniform(10, 100, 5)
    model = lumped.Model(n_dof=5, mass=m, stiffness=k, damping=c, boundaries="left")
    datas, f_true, zeta_true = ema_system()
    np.testing.assert_allclose(zeta_true, model.get_damping_ratios(), rtol=1e-9)
    freq = datas[0].omega / (2 * np.pi)
    assert freq[0] == pytest.approx(10.0) and freq[-1] == pytest.approx(1700.0)
    assert freq.size == 5000
    frf = model.get_FRF_matrix(freq=np.linspace(10.0, 1700.0, 5000)[::500], frf_method="f")[0]
    for j in range(5):
        np.testing.assert_allclose(frf[j], datas[j].response[::500], rtol=1e-9)


def test_ema_acceptance_frequencies_and_dampings():
    datas, f_true, zeta_true = ema_system()
    res = fit_shared(datas, 5, delay=False, start="rational")
    assert isinstance(res, SharedFitResult) and res.success
    f = np.array([m.frequency_hz for m in res.modes])
    zeta = np.array([m.zeta for m in res.modes])
    assert f.size == 5
    # sdypy-EMA's criteria: within 1 Hz or 2 % in frequency, 2 % in damping (each mode)
    assert np.all(np.abs(f - f_true) <= np.maximum(1.0, 0.02 * f_true))
    assert np.all(np.abs(zeta - zeta_true) <= 0.02 * zeta_true)
    # far inside them. Measured under the default (Zen), Haswell, SkylakeX and Prescott
    # kernels: 4.2e-15 (frequency), 7.1e-14 (damping), 6.7e-14 .. 3.3e-13 (worst channel's
    # max rel. error: the data's own rounding, np.linalg.inv per frequency). The bounds
    # leave 300x over the worst kernel; before the warm restarts' push was scaled to the
    # residual (solvers/shared_stage.warm_push) one kernel ended at the iteration limit at
    # 3.1e-10 (success False) while another converged at 5e-11
    assert np.max(np.abs(f - f_true) / f_true) < 1e-12
    assert np.max(np.abs(zeta - zeta_true) / zeta_true) < 2e-11
    assert np.all(res.max_rel_errors < 1e-10)
    assert all(m.is_stable() and m.is_minimum_phase() for m in res.models)
    # residues: the driving point's are -j r with r > 0 (positive modal mass)
    assert all(m.residues[0].imag < 0 for m in res.modes)


# ------------------------------------------------------------------ Moheimani's beam
SENSORS = (0.075, 0.3, 0.55, 0.9, 1.2)


def beam_datas(zeta=0.01, n_modes=30, omega_max=500.0, n_points=800):
    """Moheimani's simply-supported beam (SPEC §4), actuator at r1 = 0.075 m, one channel
    per sensor position in SENSORS, modal damping ``zeta``, log grid 5..omega_max rad/s."""
    w = np.geomspace(5.0, omega_max, n_points)
    s = 1j * w[:, None]
    out = []
    for r2 in SENSORS:
        wi, fi = moheimani_modes(n_modes, r2=r2)
        g = np.sum(fi / (s * s + 2 * zeta * wi * s + wi * wi), axis=1)
        out.append(fc.FrequencyData(w, g, f"r2={r2}"))
    return out


BEAM_ZEROS = ["minimum-phase"] + ["free"] * (len(SENSORS) - 1)


@pytest.fixture(scope="module")
def beam_fit():
    return fit_shared(beam_datas(), 6, delay=False, zeros=BEAM_ZEROS, start="rational")


def test_beam_modes_within_half_percent(beam_fit):
    wi, _ = moheimani_modes(30)
    in_band = wi[wi < 500.0]                                 # modes 1..5
    found = np.array([m.omega_n for m in beam_fit.modes])
    for w in in_band:
        assert np.min(np.abs(found - w)) / w < 0.005
        assert np.min(np.abs(found - w)) / w < 2e-5          # measured: <= 1.1e-5
    for m in beam_fit.modes:
        if m.omega_n < 500.0:
            # measured: 1.5e-3 for the fifth (at the band edge, trading with the modes
            # above it) since the start fits each channel's constant (max rel. error 0.0109,
            # was 0.0248 with 0.8e-3 there)
            assert m.zeta == pytest.approx(0.01, rel=3e-3)
    assert ([mod.structure.zeros == "minimum-phase" for mod in beam_fit.models]
            == [True] + [False] * 4)
    assert all(mod.is_stable() for mod in beam_fit.models)


def test_beam_non_collocated_channels_beat_single_channel_fits(beam_fit):
    # non-collocated channels are non-minimum phase (residues change sign): fc.fit cannot
    # follow them (max rel. error >= 0.16), zeros="free" can
    datas = beam_datas()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for c in range(1, len(SENSORS)):
            single = fc.fit(datas[c], n_sections=6, delay=False)
            assert beam_fit.max_rel_errors[c] <= single.max_rel_error
            assert beam_fit.rms_rel_errors[c] <= single.rms_rel_error
            assert beam_fit.max_rel_errors[c] < 0.012


def test_beam_six_shared_sections_are_a_compromise(beam_fit):
    # one pole set for everything: the sixth shared section stands in for modes 6..30 above
    # the band for all channels at once; measured max rel. errors 0.0248 (collocated; its
    # own fc.fit at 6 sections: 0.00306), 0.0115, 0.0078, 0.0021, 0.0066 from the strictly
    # proper start; with a constant per channel in the start 0.0089 (2.9x its own fit),
    # 0.0109 the worst channel
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        single = fc.fit(beam_datas()[0], n_sections=6, delay=False)
    assert single.max_rel_error == pytest.approx(0.00306, rel=0.01)
    assert beam_fit.max_rel_errors[0] > 2 * single.max_rel_error
    assert np.max(beam_fit.max_rel_errors) < 0.013


@pytest.fixture(scope="module")
def beam_own():
    """5 shared sections (the 5 modes in the band) + 1 section of each channel's own (the
    out-of-band modes as that channel sees them) = 6 sections per channel, default
    max_iter (its polish: 376 IPOPT iterations with one rescaled restart, measured; 410
    without the restart, which exceeded the default 2 x 200)."""
    return fit_shared(beam_datas(), 5, delay=False, zeros=BEAM_ZEROS, channel_sections=1,
                      start="rational")


@pytest.fixture(scope="module")
def beam_balanced():
    return fit_shared(beam_datas(), 5, delay=False, zeros=BEAM_ZEROS, channel_sections=1,
                      balance_channels=True, start="rational")


def _check_beam_modes(res):
    wi, _ = moheimani_modes(30)
    found = np.array([m.omega_n for m in res.modes])
    assert found.size == 5 and len(res.poles) == 10                  # only the shared poles
    np.testing.assert_allclose(found, wi[:5], rtol=0.005)             # 0.5 %
    np.testing.assert_allclose(found, wi[:5], rtol=1e-4)              # measured <= 1e-5
    assert all(len(m.residues) == len(SENSORS) for m in res.modes)
    # each channel's own section sits above the band (measured 596..640 rad/s: mode 6 is
    # 613) and is not a mode
    for p in res.channel_poles:
        assert p.size == 2 and np.all(np.abs(p) > 500.0) and np.all(p.real < 0)
    assert all(m.n_sections == 6 for m in res.models)
    assert all(mod.is_stable() for mod in res.models)
    assert res.models[0].is_minimum_phase()


def test_beam_channel_sections_modes_and_errors(beam_own):
    # the collocated channel's model is in the same class as its own fit (6 minimum-phase
    # sections), so in least squares it can tie its own fit at best: it cannot, as its 5
    # in-band poles are shared. Measured max rel. errors 0.003078 (own fit 0.003056, 0.7 %
    # worse), 0.00548, 0.00070, 0.00061, 0.00179 (vs 0.0248, 0.0115, 0.0078, 0.0021, 0.0066
    # with 6 shared sections)
    _check_beam_modes(beam_own)
    assert beam_own.success and beam_own.stages[-1].success
    # the 25 modes above the band leave a residual far above the (zero) noise of exact data:
    # "poor-fit", and the message names the next step; the optimiser's words in details
    assert beam_own.status == "poor-fit"
    assert beam_own.message.startswith("poor-fit: converged, but the residual of channels")
    assert "pass n_sections=6 or more" in beam_own.message
    assert "channel_sections=2" in beam_own.message
    assert beam_own.details["final_stage"]["message"].startswith(
        "converged (relative stationarity")
    assert "User_Requested_Stop" not in beam_own.message
    assert "after 1 rescaled restarts" in beam_own.stages[-1].solver_status
    assert beam_own.nit <= 400                                          # measured 376
    assert beam_own.max_rel_errors[0] == pytest.approx(0.0030775, rel=1e-4)
    assert beam_own.summary().startswith("5 channels, 5 shared sections + 1 per channel")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        single = fc.fit(beam_datas()[0], n_sections=6, delay=False)
    assert beam_own.max_rel_errors[0] <= 1.01 * single.max_rel_error
    assert beam_own.rms_rel_errors[0] <= 1.01 * single.rms_rel_error
    assert np.all(beam_own.max_rel_errors < 0.006)


def test_beam_collocated_channel_no_worse_than_single_fit(beam_balanced):
    # every channel's max rel. error no worse than its own single-channel fit at
    # the same number of sections per channel: 5 shared + 1 own (balance_channels) vs the
    # channel alone at 5 + 1 = 6 sections (fit_shared on it; for the collocated channel
    # also fc.fit at 6 sections, the same model class). Measured ratios 0.39, 0.51, 0.49,
    # 0.69, 0.84 after 2 warm-started reweighted rounds and one solve of the last weighted
    # problem to the stages' test (499 IPOPT iterations in all); the price is least-squares
    # optimality: the collocated channel's RMS error is 1.37x its own fit's.
    res = beam_balanced
    _check_beam_modes(res)
    assert res.success and res.stages[-1].success
    assert res.message.startswith("poor-fit: converged")
    assert res.message.endswith("every channel is within its own fit's max rel. error")
    assert res.details["balance"]["exceed"] == [] and res.details["balance"]["rounds"] >= 1
    assert res.nit <= 600                                               # measured 499
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        single = fc.fit(beam_datas()[0], n_sections=6, delay=False)
    assert res.max_rel_errors[0] <= single.max_rel_error
    assert res.single_max_rel_errors[0] == pytest.approx(single.max_rel_error, rel=1e-3)
    assert np.all(res.max_rel_errors <= res.single_max_rel_errors)
    assert res.max_rel_errors[0] < 0.5 * single.max_rel_error          # measured 0.38
    assert res.rms_rel_errors[0] < 1.5 * single.rms_rel_error          # measured 1.36
    assert res.options["balance_channels"] and res.options["channel_sections"] == 1


# ------------------------------------------------------------------ options, export, errors
def _two_mode_datas(delays=(0.0, 0.0), n=200):
    w = np.linspace(1.0, 30.0, n)
    s = 1j * w
    poles = [(5.0, 0.02), (17.0, 0.03)]

    def g(res, h):
        return np.exp(-s * h) * sum(r / (s * s + 2 * z * p * s + p * p)
                                    for r, (p, z) in zip(res, poles))
    return [fc.FrequencyData(w, g((1.0, 2.0), delays[0]), "a"),
            fc.FrequencyData(w, g((1.5, 0.5), delays[1]), "b")]


def test_per_channel_delays_and_sequential_start():
    datas = _two_mode_datas(delays=(0.01, 0.02))
    for start in ("rational", "sequential"):
        res = fit_shared(datas, 2, delay="per-channel", start=start)
        assert np.all(res.max_rel_errors < 1e-6), (start, res.max_rel_errors)
        # a delay trades against a far zero pair at 45 degrees (exp(-sh)(1 + sh + s^2 h^2/2)
        # = 1 + O(s^3 h^3)): the absolute delays are within 6e-4 s (measured), their
        # difference, which the far zeros cannot mimic, within 1.3e-5 s (measured 1.23e-5
        # from the rational start with a constant per channel, below 1e-5 before)
        np.testing.assert_allclose(res.delays, [0.01, 0.02], atol=1e-3)
        assert res.delays[1] - res.delays[0] == pytest.approx(0.01, abs=2.5e-5)
        np.testing.assert_allclose(sorted(m.omega_n for m in res.modes), [5.0, 17.0],
                                   rtol=1e-6)
    assert [s.stage for s in res.stages] == [0, 1, 2, 3]


@pytest.mark.parametrize("delay", ["per-channel", "shared"])
def test_rational_start_removes_a_delay_of_many_turns(monkeypatch, delay):
    # two modes, delays of 1.5 s and 2 s (both 2 s with one shared delay): 45 and 60 rad at
    # the top of the 1-30 rad/s band (exact data). Vector fitting of the delayed data
    # spends the shared poles on the delay; with each channel's group delay removed first
    # the fit is exact (measured: max rel. error 8e-10 per-channel, 5e-10 shared, delays
    # within 5e-5 relative; without the removal RMS 0.96-0.99)
    import freqid_casadi.modal.shared as shared

    delays = (1.5, 2.0) if delay == "per-channel" else (2.0, 2.0)
    datas = _two_mode_datas(delays=delays)
    res = fit_shared(datas, 2, delay=delay, start="rational")
    assert np.all(res.max_rel_errors < 1e-7), res.max_rel_errors
    np.testing.assert_allclose(res.delays, delays, rtol=1e-3)
    monkeypatch.setattr(shared, "significant_group_delay", lambda data: 0.0)
    off = fit_shared(datas, 2, delay=delay, start="rational")
    assert np.all(off.rms_rel_errors > 0.5), off.rms_rel_errors


@pytest.mark.parametrize("start", ["rational", "sequential"])
def test_channel_sections_take_what_is_not_shared(start):
    # 1 shared section + 1 of each channel's own on exact two-mode data: one mode is shared
    # (the modal table lists it alone), the other is found by each channel's own section
    from freqid_casadi.core.modes import modes

    datas = _two_mode_datas()
    res = fit_shared(datas, 1, delay=False, channel_sections=1, start=start)
    assert res.success and np.all(res.max_rel_errors < 1e-8)
    assert len(res.modes) == 1 and len(modes(res)) == 1 and res.poles.size == 2
    shared = res.modes[0].omega_n
    other = 17.0 if shared < 10 else 5.0
    assert min(abs(shared - 5.0), abs(shared - 17.0)) < 1e-6
    for p in res.channel_poles:
        np.testing.assert_allclose(np.abs(p), other, rtol=1e-6)
    assert all(m.n_sections == 2 for m in res.models)
    assert res.to_control().nstates == 8 and res.channel_sections == 1 and res.n_shared == 1


def test_to_control_outputs_every_channel_with_delays():
    datas = _two_mode_datas(delays=(0.0, 0.02))
    res = fit_shared(datas, 2, delay="per-channel", start="rational")
    sys = res.to_control()
    assert sys.ninputs == 1 and sys.noutputs == 2
    np.testing.assert_allclose(sys.output_delays, res.delays)
    w = datas[0].omega[::20]
    fr = sys(1j * w)                                      # (outputs, inputs, points)
    for c, m in enumerate(res.models):
        np.testing.assert_allclose(fr[c, 0] * np.exp(-1j * w * res.delays[c]),
                                   m.frequency_response(w), rtol=1e-8)
    two = res.to_control(references=["x", "y"])
    assert two.ninputs == 2 and two.input_references == ("x", "y")
    assert np.allclose(two.D[0, 1], 0) and np.allclose(two.B[:, 1][:two.nstates // 2], 0)


def test_free_zeros_model_json_round_trip(beam_fit):
    m = beam_fit.models[2]
    assert m.structure.zeros == "free" and not m.is_minimum_phase()
    back = RationalDelayModel.from_json(m.to_json())
    assert back == m
    assert np.array_equal(back.frequency_response([10.0, 100.0]),
                          m.frequency_response([10.0, 100.0]))


def test_input_errors():
    datas = _two_mode_datas()
    other = fc.FrequencyData(datas[0].omega * 1.01, datas[1].response)
    with pytest.raises(DataError, match="omega grid"):
        fit_shared([datas[0], other], 2)
    with pytest.raises(DataError, match="sequence of FrequencyData"):
        fit_shared([], 2)
    with pytest.raises(OptionError, match="delay"):
        fit_shared(datas, 2, delay="both")
    with pytest.raises(OptionError, match="zeros"):
        fit_shared(datas, 2, zeros=["free"])
    with pytest.raises(OptionError, match="n_sections"):
        fit_shared(datas, 0)
    with pytest.raises(OptionError, match="start"):
        fit_shared(datas, 2, start="fastest")
    for bad in (-1, True, 1.5):
        with pytest.raises(OptionError, match="channel_sections"):
            fit_shared(datas, 2, channel_sections=bad)
    with pytest.raises(DataError, match="weights"):
        fit_shared(datas, 2, weights=-np.ones(200))


def test_integrator_in_every_channel():
    datas = [fc.FrequencyData(d.omega, d.response / (1j * d.omega), d.name)
             for d in _two_mode_datas()]
    res = fit_shared(datas, 2, integrator=True, delay=False, start="rational")
    assert res.success and np.all(res.max_rel_errors < 1e-8)
    assert all(m.integrator for m in res.models)
    np.testing.assert_allclose([m.omega_n for m in res.modes], [5.0, 17.0], rtol=1e-8)
    assert res.poles.size == 4                      # the integrator's pole is not listed


def test_weights_scale_the_channels():
    datas = _two_mode_datas()
    w = np.ones((2, 200))
    w[1, 100:] = 0.0                              # the second channel's upper half ignored
    res = fit_shared(datas, 2, delay=False, weights=w, start="rational")
    assert res.success and np.all(res.max_rel_errors < 1e-6)
    same = fit_shared(datas, 2, delay=False, weights=2.0, start="rational")
    assert np.all(same.max_rel_errors < 1e-6)
    with pytest.raises(DataError, match="broadcastable"):
        fit_shared(datas, 2, weights=np.ones(7))


@pytest.mark.parametrize("local", [0, 1])
def test_block_termination_measures_equal_dense_ones(local):
    # the shared stages' test uses the block structure of the stacked weighted Jacobian;
    # the same numbers from the dense Jacobian (solvers.termination.projected_fraction)
    from freqid_casadi.solvers.shared_termination import (blocks, block_projected_fraction,
                                                          column_norms, gradient_and_norms)
    from freqid_casadi.solvers.termination import projected_fraction

    rng = np.random.default_rng(3)
    prob = SharedProblem(np.linspace(1.0, 30.0, 40), rng.normal(size=(3, 40)) +
                         1j * rng.normal(size=(3, 40)), rng.uniform(0.5, 2.0, (3, 40)),
                         np.ones(3), [5.0, 17.0], False, "per-channel",
                         np.array([False, True, False]), 0.1,
                         None if not local else [[8.0], [9.0], [10.0]])
    z = rng.uniform(0.1, 1.0, prob.n_vars)
    r, A = blocks(prob, z)
    ns, no = prob.n_shared, prob.n_own
    dense = np.zeros((r.size, prob.n_vars))
    for c in range(3):
        rows = slice(c * r.shape[1], (c + 1) * r.shape[1])
        dense[rows, :ns] = A[c, :, :ns]
        dense[rows, ns + c * no:ns + (c + 1) * no] = A[c, :, ns:]
    cost, grad = prob.gradient(z)
    assert float(r.ravel() @ r.ravel()) == pytest.approx(cost, rel=1e-12)
    np.testing.assert_allclose(2 * dense.T @ r.ravel(), grad, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(column_norms(prob, z), np.linalg.norm(dense, axis=0),
                               rtol=1e-12)
    c2, g2, _ = gradient_and_norms(prob, z)
    assert c2 == pytest.approx(cost, rel=1e-13)
    np.testing.assert_allclose(g2, grad, rtol=1e-12, atol=1e-14)
    free = np.ones(prob.n_vars, bool)
    free[[0, ns + 2]] = False
    want = projected_fraction(r.ravel(), dense, free)
    assert 0.01 < want < 0.999
    assert block_projected_fraction(prob, z, free) == pytest.approx(want, rel=1e-8)


def test_solve_stage_stops_at_a_relatively_stationary_point():
    # noisy two-mode data, 2 shared sections: the solve ends by the scale-free test (or
    # IPOPT's tolerance), and a solve started at its solution returns it without iterating
    from freqid_casadi.solvers.shared_stage import solve_stage

    datas = _two_mode_datas()
    rng = np.random.default_rng(5)
    phi = np.array([d.response for d in datas]) * (1 + 0.01 * rng.normal(size=(2, 200)))
    prob = SharedProblem(datas[0].omega, phi, np.ones((2, 200)), np.abs(phi[:, 0]),
                         [5.0, 17.0], False, False, np.array([True, True]), 1.0)
    z0 = prob.join(np.array([[1.0, 0.05], [1.0, 0.05]]), np.ones(2), np.zeros(2),
                   np.ones((2, 2, 2)))
    res = solve_stage(prob, z0)
    assert res["success"] and res["message"].startswith("converged")
    assert 0 < res["nit"] < 200 and res["cost"] < 0.1 * prob.cost(z0)     # measured 26 it, 0.04
    again = solve_stage(prob, res["x"])
    assert again["nit"] == 0 and again["status"] == "start-stationary" and again["stationary"]
    assert again["message"].startswith("converged: the start is stationary")
    off = solve_stage(prob, z0, max_iter=3, termination=None)
    assert not off["success"] and off["message"].startswith("not converged")


def test_beam_sequential_stages_end_relatively_stationary():
    # every stage ends by the scale-free test; before the snap onto the bounds the last
    # two ended by IPOPT's tolerance at max cos(r, J_j) 2.7e-3 / 2.2e-3 (a minimum-phase
    # channel's numerator coefficient kept 6.8e-10 off 0 by the barrier). The sequential
    # start lands in a poor optimum on this beam (channel 1: max rel. error 1.97, the same
    # before this change); the rational start is the default.
    res = fit_shared(beam_datas(), 6, delay=False, zeros=BEAM_ZEROS, start="sequential")
    assert res.success
    assert all(s.message.startswith("converged (relative stationarity") for s in res.stages)


def test_best_start_skips_the_sequential_loop_only_when_it_cannot_help(monkeypatch):
    # exact two-mode data: the rational start explains them to their noise (the numerical
    # floor), so "best" keeps it without the sequential loop and says why
    import freqid_casadi.modal.shared as shared

    datas = _two_mode_datas()
    res = fit_shared(datas, 2, delay=False)
    assert res.details["start"] == "rational" and res.status == "ok"
    assert "explains every channel" in res.details["start_skipped"]
    assert set(res.details["start_max_rel_errors"]) == {"rational"}
    # above the size limit the loop is not run either (and the reason names the override)
    monkeypatch.setattr(shared, "BEST_SEQUENTIAL_LIMIT", 100)
    noisy = [fc.FrequencyData(d.omega, d.response * (1 + 0.01 * np.cos(3.7 * d.omega)), d.name)
             for d in datas]
    big = fit_shared(noisy, 1, delay=False)
    assert big.details["start"] == "rational"
    assert "start='sequential'" in big.details["start_skipped"]
    # below it, a rational start that does not explain the data brings in the loop
    monkeypatch.setattr(shared, "BEST_SEQUENTIAL_LIMIT", 10 ** 9)
    both = fit_shared(noisy, 1, delay=False)
    assert "start_skipped" not in both.details
    assert set(both.details["start_max_rel_errors"]) == {"rational", "sequential"}

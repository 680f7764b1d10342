"""Tests of the transcription of the thesis's MATLAB code (Appendix A).

* create_jacob.m against finite differences of its own residuals: every column, with the
  places where it is not ``-d eps_p/d beta`` asserted (not skipped);
* the pieces: gain ratio, damping update, tol1 growth, stage-0 windows, K0, the new
  section, pinv, the main loop's condition, tf_approx vs RationalDelayModel;
* one row per Table 4.1 entry: the transcription's max and RMS relative error against the
  published number (strict; xfail with the measured value where it does not reproduce).
"""

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.errors import OptionError, SolverError
from freqid_casadi.studies import thesis_matlab as tm

RNG = np.random.default_rng(18)


def _data(n=40, integrator=True):
    omega = np.logspace(-1, 2, n)
    s = 1j * omega
    phi = 3.0 * np.exp(-0.01 * s) * (s**2 + 0.3 * s + 25) / (s**2 + 0.2 * s + 16)
    return s, (phi / s if integrator else phi)


def _section():
    return np.array([1.3, 0.4, 2.5, 0.8, 0.3, 4.0]) * RNG.uniform(0.8, 1.2, 6)


def _fd(fun, x, rel=1e-6):
    """Central differences, shape (len(fun(x)), len(x))."""
    cols = []
    for i in range(len(x)):
        step = rel * max(abs(x[i]), 1e-3)
        xp, xm = x.copy(), x.copy()
        xp[i] += step
        xm[i] -= step
        cols.append((fun(xp) - fun(xm)) / (2 * step))
    return np.column_stack(cols)


def _close(a, b, rtol=1e-6):
    """Column-wise relative closeness."""
    scale = np.maximum(np.linalg.norm(b, axis=0), 1e-12)
    return np.all(np.linalg.norm(a - b, axis=0) / scale < rtol)


# ------------------------------------------------------------------ create_jacob vs FD
@pytest.mark.parametrize("integrator", [True, False])
def test_stage0_jacobian_columns_against_finite_differences(integrator):
    s, phi = _data(5, integrator)
    beta = np.array([0.004, 2.7])
    t = 1200.0
    fi = tm.first_factor(s, *beta, integrator)
    J = tm.create_jacob(s, None, beta, phi, fi, t, integrator)
    assert J.shape == (5, 3) and np.all(J[:, 0] == 0)          # l.14: the dropped column
    J = J[:, 1:]
    fd = _fd(lambda b: tm.stage0_residual(s, phi, b, t, integrator), beta)
    # delay column (l.46): the negative derivative, as the step +pinv(A+mu I)*g needs
    assert _close(J[:, 0], -fd[:, 0])
    # gain column (l.48): data part scaled by t = 1200 (the delay column is not) and the
    # barrier part with the wrong sign: J = -t d eps_p/dK - 2/K
    assert _close(J[:, 1], -t * fd[:, 1] - 2 / beta[1])
    assert not _close(J[:, 1], -fd[:, 1], rtol=1e-2)


@pytest.mark.parametrize("integrator", [True, False])
def test_section_jacobian_columns_against_finite_differences(integrator):
    s, phi = _data(40, integrator)
    t = 20.0
    ctnow = np.column_stack([[0.01, 2.9, 0, 0, 0, 0], _section()])
    beta_i = _section()
    n_prev = 2 + 6 * (ctnow.shape[1] - 1)

    def residual(x):                       # eps_p of cost_and_coeffs.m l.192-195
        ct = np.concatenate([x[:2], np.zeros(4), x[2:n_prev]]).reshape(6, -1, order="F")
        fi = tm.tf_approx(s, ct, x[n_prev:], integrator)
        return tm.stage_residual(phi, fi, x[n_prev:], ct, t)

    x = np.concatenate([ctnow[:2, 0], ctnow[:, 1:].reshape(-1, order="F"), beta_i])
    fi = tm.tf_approx(s, ctnow, beta_i, integrator)
    J = tm.create_jacob(s, ctnow, beta_i, phi, fi, t, integrator)[:, 1:]
    assert J.shape == (40, len(x)) == (40, 14)
    fd = _fd(residual, x)
    # delay column: l.22 lacks t_, J = -(1/t) d eps_p/dh
    assert _close(J[:, 0], -fd[:, 0] / t)
    assert not _close(J[:, 0], -fd[:, 0], rtol=1e-2)
    # every other column (K: l.24; sections: l.30-36 and l.54-60): data part right, barrier
    # part -1/beta with the wrong sign, J = -d eps_p/d beta - 2/beta
    for i in range(1, len(x)):
        assert _close(J[:, i], -fd[:, i] - 2 / x[i]), i
        assert not _close(J[:, i], -fd[:, i], rtol=1e-3), i


def test_loop_counts_the_new_sections_barrier_twice_after_a_step():
    # cost_and_coeffs.m l.246-250 / l.269-273: ctnow already ends with the new section, so
    # its logs enter once as beta_i and once in coeffs_constraint (at l.195 only once).
    s, phi = _data(10)
    ctnow = np.column_stack([[0.01, 2.9, 0, 0, 0, 0], _section()])
    beta_i = _section()
    fi = tm.tf_approx(s, ctnow, beta_i)
    once = tm.stage_residual(phi, fi, beta_i, ctnow, 5.0)
    twice = tm.stage_residual(phi, fi, beta_i, np.column_stack([ctnow, beta_i]), 5.0)
    np.testing.assert_allclose(twice - once, -np.sum(np.log(beta_i)), rtol=1e-12)
    assert tm.coeffs_constraint(ctnow).tolist() == [2.9] + ctnow[:, 1].tolist()


def test_residual_subtracts_the_barrier_from_every_complex_residual():
    s, phi = _data(10)
    ctnow = np.array([[0.01, 2.9, 0, 0, 0, 0]]).T
    beta_i = _section()
    fi = tm.tf_approx(s, ctnow, beta_i)
    r = tm.stage_residual(phi, fi, beta_i, ctnow, 7.0)
    barrier = np.sum(np.log(beta_i)) + np.log(2.9)
    np.testing.assert_allclose(r, 7.0 * (phi / fi - 1) - barrier, rtol=1e-12)
    # a negative coefficient gives MATLAB's complex log, not NaN
    assert tm.matlab_log(-2.0) == pytest.approx(np.log(2.0) + 1j * np.pi)


# ------------------------------------------------------------------ the pieces
def test_gain_ratio():
    eps_p, eps_new = np.array([3 + 4j]), np.array([1 + 0j])       # 25 -> 1
    delta, g = np.array([1.0, 2.0]), np.array([0.5, -1.0])
    # (25 - 1) / (delta' (mu delta + g)) = 24 / (1*(2+0.5) + 2*(4-1)) = 24 / 8.5
    assert tm.gain_ratio(eps_p, eps_new, delta, 2.0, g) == pytest.approx(24 / 8.5)
    assert np.isnan(tm.gain_ratio(eps_p, np.array([np.nan + 0j]), delta, 2.0, g))


@pytest.mark.parametrize("rho, factor", [(0.5, 1.0), (1.0, 1 / 3), (0.9, 1 - 0.8**3), (0.95, 1 / 3),
                                         (0.25, 1.125), (0.75, 1 - 0.125)])
def test_damping_update_after_success(rho, factor):
    mu, v = tm.update_damping(4.0, 16.0, rho)
    assert mu == pytest.approx(4.0 * factor) and v == 2.0


@pytest.mark.parametrize("rho", [0.0, -3.0, np.nan])
def test_damping_update_after_failure(rho):
    assert tm.update_damping(4.0, 8.0, rho) == (32.0, 16.0)


def test_tol1_grows_tenfold_every_1000_iterations():
    tol1 = 1e-20
    for k in range(1, 3001):
        tol1 = tm.grow_tol1(k, tol1)
        if k == 999:
            assert tol1 == 1e-20
        if k == 1000:
            assert tol1 == pytest.approx(1e-19)
    assert tol1 == pytest.approx(1e-17)


def test_stage0_window_grows_1_3_5_points():
    assert tm.stage0_windows(1, 5) == [1, 3, 5]
    assert tm.stage0_windows(4, 5) == [4, 6, 8]       # start_dom offsets every window


def test_stage0_start_and_new_section():
    data = fc.systems.G_A()
    s = 1j * data.omega
    assert tm.stage0_start(data.response, s, True)[1] == pytest.approx(
        abs(data.response[0]) * data.omega[0], rel=1e-14)       # K0 = |Phi_1| omega_1
    assert tm.stage0_start(data.response, s, False).tolist() == [0.0, abs(data.response[0])]
    sec = tm.new_section(22.2)
    assert sec == pytest.approx([30, 0.5 * 30**0.5, 22.2 * 30**0.5, 30, 0.5 * 30**0.5,
                                 22.2 * 30**0.5])
    np.testing.assert_allclose(tm.tf_approx(s, None, sec), 1.0, atol=1e-13)


def test_stage0_stalls_near_its_start():
    # Phi = 4/s. The residual (Phi-fi)/fi - log(K)/1200 vanishes at h = 0 and
    # 4/K - 1 = log(K)/1200, i.e. K* = 3.9954 (biased by the -(1/t) log beta term), but the
    # gain column of create_jacob is ~1200x too large (data part times t), so the gain ratio
    # of every accepted step is ~1/1200, mu doubles (max(1/3, 1-(2 rho-1)^3) ~ 2) and the
    # steps die out: K moves from K0 = |Phi_1| omega_1 = 4 by only ~1.5e-5.
    omega = np.logspace(-2, 3, 500)
    phi = 4 / (1j * omega)
    cost, coeffs, frep, nit = tm.integrator_stage(phi, omega, 1, 5, integrator=True)
    k_star = 4.0
    for _ in range(50):
        k_star = 4 / (1 + np.log(k_star) / 1200)
    assert coeffs.shape == (6, 1) and coeffs[2:, 0].tolist() == [0, 0, 0, 0]
    assert coeffs[0, 0] == 0.0 and nit > 0
    assert 0 < 4.0 - coeffs[1, 0] < 3e-5                      # moved, but hardly
    assert abs(coeffs[1, 0] - k_star) > 4e-3                  # the stationary point: 3.9954
    np.testing.assert_allclose(frep, coeffs[1, 0] / (1j * omega), rtol=1e-14)
    assert cost == pytest.approx(abs(4 / coeffs[1, 0] - 1), rel=1e-6)   # RMS over 5 points


def test_main_loop_condition_never_ends_as_printed():
    assert tm.main_loop_continues(8, np.inf)
    assert tm.main_loop_continues(9, np.inf)          # cost_all stays Inf: never False
    assert tm.main_loop_continues(100, np.inf)
    assert not tm.main_loop_continues(9, 1e-3)
    assert tm.main_loop_continues(3, 1e-3)


def test_matlab_pinv_tolerance_and_nan():
    A = np.diag([1.0, 1e-17, 2.0])
    P = tm.matlab_pinv(A)
    assert P[1, 1] == 0 and P[0, 0] == 1 and P[2, 2] == 0.5
    with pytest.raises(SolverError, match="NaN or Inf"):
        tm.matlab_pinv(np.array([[1.0, np.nan], [0, 1]]))


def test_cost_func_is_the_rms_relative_error():
    H, Hn = np.array([2.0, 1.0 + 1j]), np.array([1.0, 1.0])
    assert tm.cost_func(H, Hn) == pytest.approx(np.sqrt((1 + 1) / 2))


@pytest.mark.parametrize("integrator", [True, False])
def test_tf_approx_is_the_models_response(integrator):
    omega = np.logspace(-1, 2, 30)
    ctnow = np.column_stack([[0.02, 1.7, 0, 0, 0, 0], _section(), _section()])
    beta = np.concatenate([ctnow[:2, 0], ctnow[:, 1:].reshape(-1, order="F")])
    model = fc.RationalDelayModel(fc.Structure(2, integrator, True), beta)
    np.testing.assert_allclose(tm.tf_approx(1j * omega, ctnow, None, integrator),
                               model.frequency_response(omega), rtol=1e-12)
    np.testing.assert_allclose(tm.tf_approx(1j * omega, ctnow[:, :2], ctnow[:, 2], integrator),
                               model.frequency_response(omega), rtol=1e-12)


def test_run_small_and_bad_options():
    data = fc.systems.G_A()
    res = tm.run_thesis_matlab(data, n_sections=2, integrator=True)
    assert res.n_sections == 2 and res.coeffs.shape == (6, 3) and len(res.history) == 3
    assert res.status == "stopped-at-n-sections" and res.model is not None
    np.testing.assert_allclose(res.model.relative_error(data), res.rel_error, rtol=1e-9)
    assert res.max_rel_error == pytest.approx(np.max(res.rel_error))
    assert res.history[1].window >= 1 and res.history[-1].max_rel_error == res.max_rel_error
    assert res.max_rel_error < 3.0 < res.history[0].max_rel_error     # stage 0: 37
    for bad in (dict(n_sections=-1), dict(n_sections=1.5), dict(n_sections=2, max_inner=0),
                dict(n_sections=2, time_budget=-1.0)):
        with pytest.raises(OptionError):
            tm.run_thesis_matlab(data, integrator=True, **bad)


def test_deterministic_and_cap_recorded():
    data = fc.systems.G_B()
    a = tm.run_thesis_matlab(data, n_sections=2, integrator=False, max_inner=50)
    b = tm.run_thesis_matlab(data, n_sections=2, integrator=False, max_inner=50)
    assert np.array_equal(a.coeffs, b.coeffs) and a.nit == b.nit
    assert a.max_inner == 50 and a.n_capped > 0
    assert all(k <= 50 for st in a.history[1:] for k in st.pass_nit)
    assert [len(st.pass_nit) for st in a.history[1:]] == [10, 10]     # t = 1 ... 20^9


# ------------------------------------------------------------------ Table 4.1 rows
#: Cap of the row tests: each LM loop (one stage-0 window or one barrier problem) stops
#: after ROW_MAX_INNER iterations (the printed loops have no cap; uncapped, one stage of A
#: runs ~14000 iterations and the 17 stages take ~30 min on the loaded 2-core machine), so
#: that the three rows finish in about 1.5 min. The uncapped runs are in
#: results/thesis_matlab (python scripts/thesis_matlab.py). The trajectories are sensitive
#: to rounding (another BLAS may change the iteration counts and the stage that fails).
ROW_MAX_INNER = 100

_MEASURED = {}


def _row(name):
    if name not in _MEASURED:
        row = tm.TABLE_4_1[name]
        data = getattr(fc.systems, f"G_{name}")()
        _MEASURED[name] = tm.run_thesis_matlab(
            data, n_sections=row["n_sections"], integrator=row["integrator"],
            max_inner=ROW_MAX_INNER)
    return _MEASURED[name]


#: Measured with ROW_MAX_INNER = 100 (python -m pytest tests/test_thesis_matlab.py -m slow -s).
_A_STOP = ("capped run (max_inner=100) stops at stage 6: cost_and_coeffs returns NaN "
           "(a[4] = -0.2667 < 0, l.313), so 5 of 17 sections")
_C_STOP = ("capped run (max_inner=100) stops at stage 1: cost_and_coeffs returns NaN "
           "(zeta_den[1] = -3.396 < 0, l.313), so 0 of 27 sections")
#: Uncapped (results/thesis_matlab, 1060 s): A reaches 17 sections, max 0.01191 <= 0.2549
#: (reproduces); B stops at stage 5 (zeta_den[5] < 0), C at stage 3 (zeta_den[1] < 0).
MAX_REASONS = {
    "A": f"{_A_STOP}; measured max 0.2364 (<= 0.2549 but at order 10, not 34; uncapped: "
         "17 sections, max 0.01191, see results/thesis_matlab)",
    "B": "measured max 2.032 > 0.0027 (9 sections, capped run max_inner=100)",
    "C": f"{_C_STOP}; measured max 287.6 > 5.9884",
}
RMS_REASONS = {
    "A": f"{_A_STOP}; measured RMS 0.04397 (<= 0.2549 but at order 10, not 34; uncapped: "
         "17 sections, RMS 0.002127)",
    "B": "measured RMS 0.7847 > 0.0027 (9 sections, capped run max_inner=100)",
    "C": f"{_C_STOP}; measured RMS 22.83 > 5.9884",
}


def _params(reasons):
    return [pytest.param(n, marks=pytest.mark.xfail(strict=True, raises=AssertionError,
                                                    reason=reasons[n]))
            if reasons.get(n) else n for n in ("A", "B", "C")]


def _show(name, res):
    row = tm.TABLE_4_1[name]
    print(f"\n{name}: transcription (max_inner={ROW_MAX_INNER}) {res.n_sections} sections, "
          f"max {res.max_rel_error:.4g}, RMS {res.rms_rel_error:.4g}, delay {res.delay:.4g} s, "
          f"{res.status}; thesis {row['n_sections']} sections, {row['max_rel_error']} "
          f"(delay {row['delay']} s)")


@pytest.mark.slow
@pytest.mark.parametrize("name", _params(MAX_REASONS))
def test_table_4_1_row_max_relative_error(name):
    res, row = _row(name), tm.TABLE_4_1[name]
    _show(name, res)
    assert res.n_sections == row["n_sections"]
    assert res.max_rel_error <= row["max_rel_error"]


@pytest.mark.slow
@pytest.mark.parametrize("name", _params(RMS_REASONS))
def test_table_4_1_row_rms_relative_error(name):
    # the MATLAB cost_func (cost_and_coeffs.m l.341-344) returns the RMS; the published
    # number may be that measure (SPEC §5)
    res, row = _row(name), tm.TABLE_4_1[name]
    _show(name, res)
    assert res.n_sections == row["n_sections"]
    assert res.rms_rel_error <= row["max_rel_error"]


def test_transcription_rows_feed_the_other_reports(tmp_path):
    import json

    from freqid_casadi.studies.thesis_matlab import transcription_lines, transcription_rows

    assert transcription_rows(str(tmp_path / "missing.json")) is None
    assert "Not available here" in "\n".join(transcription_lines(None))
    t = {"n_sections": 17, "max_rel_error": 0.0119, "rms_rel_error": 0.002, "delay": 0.0104,
         "iterations": 10, "wall_time": 1.0, "status": "stopped-at-n-sections"}
    bad = dict(t, n_sections=4, max_rel_error=24.2)
    path = tmp_path / "tm.json"
    path.write_text(json.dumps({"command": "python scripts/thesis_matlab.py",
                                "examples": {"A": {"transcription": t},
                                             "B": {"transcription": bad}}}))
    info = transcription_rows(str(path))
    text = "\n".join(transcription_lines(info, {"A": 6.3e-6}))
    assert "| A | 0.2549 | 0.0119 |" in text and "| yes |" in text
    assert "| B | 0.0027 | 24.2 |" in text and "4 / 9" in text
    assert "reproduces 1 of 2 published rows (A)" in text

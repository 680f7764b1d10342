"""The main loop and the public fit(): recovery, feasibility, the result's contract, errors.

Both stage solvers share one contract, written as mixins (scipy's test_least_squares style).
"""

import json
import subprocess
import sys

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.errors import DataError, OptionError, StructureError

TRUE_BETA = [0.02, 3.0,
             1.0, 0.03, 5.0, 1.0, 0.05, 8.0,
             1.0, 0.02, 40.0, 1.0, 0.01, 25.0]


def two_section_data(integrator=True, n_points=200):
    beta = list(TRUE_BETA)
    model = fc.RationalDelayModel(fc.Structure(2, integrator, True), beta)
    omega = np.logspace(-1, 2.5, n_points)
    return model, fc.FrequencyData(omega, model.frequency_response(omega), "two-section")


def _check_min_phase_stable(model):
    sys_ = model.to_control()
    import control as ct

    poles = ct.poles(sys_)
    zeros = ct.zeros(sys_)
    if model.integrator:
        # the integrator's pole at 0 is the only one allowed on the axis
        poles = np.delete(poles, np.argmin(np.abs(poles)))
    assert np.all(poles.real < 0)
    assert np.all(zeros.real < 0)
    assert model.is_stable() and model.is_minimum_phase()


class RecoveryMixin:
    method = None
    solver = None
    tol_error = None
    tol_delay = None

    def test_recovers_two_section_model_with_integrator_and_delay(self):
        _, data = two_section_data()
        res = fc.fit(data, n_sections=2, integrator=True, method=self.solver)
        assert res.max_rel_error <= self.tol_error
        assert abs(res.model.delay - TRUE_BETA[0]) <= self.tol_delay
        assert res.success
        _check_min_phase_stable(res.model)

    def test_result_fields_are_consistent(self):
        _, data = two_section_data(n_points=120)
        # (the sequential loop's stages and windows)
        res = fc.fit(data, n_sections=2, integrator=True, method=self.solver,
                     start="sequential")
        rel = res.model.relative_error(data)
        np.testing.assert_array_equal(res.rel_error, rel)
        assert res.max_rel_error == pytest.approx(np.max(rel), rel=0, abs=0)
        assert res.rms_rel_error == pytest.approx(np.sqrt(np.mean(rel ** 2)), rel=1e-14)
        assert res.method == self.method
        assert [s.stage for s in res.stages][:3] == [0, 1, 2]
        windows = [s.window for s in res.stages]
        assert windows == sorted(windows) and windows[-1] == data.n_points
        assert all(s.nit >= 0 and s.wall_time >= 0 for s in res.stages)
        assert res.wall_time >= sum(s.wall_time for s in res.stages) * 0.5


@pytest.mark.parametrize("n_sections", [2, range(1, 3)])
def test_wall_time_is_the_whole_call(n_sections):
    """FitResult.wall_time counts the whole fit() call: the automatic integrator's
    contenders, the layers after the core fit and, with an order range, every order
    (before, only the kept core fit's seconds: 0.19 and 0.01 of the call on a measured
    beam FRF at 2 sections and at 'auto')."""
    import time
    _, data = two_section_data(n_points=120)
    t0 = time.perf_counter()
    res = fc.fit(data, n_sections=n_sections)
    elapsed = time.perf_counter() - t0
    assert 0.8 * elapsed <= res.wall_time <= elapsed


class TestIpopt(RecoveryMixin):
    method = "ipopt"
    solver = "ipopt"
    tol_error = 1e-6
    tol_delay = 1e-6


class TestBarrierLM(RecoveryMixin):
    method = "barrier-lm"
    solver = fc.BarrierLMOptions(damping="marquardt")
    tol_error = 1e-6
    tol_delay = 1e-6


def test_both_methods_reach_the_same_optimum():
    """A small problem with a known solution: both constraint handlings find it."""
    model, data = two_section_data(n_points=150)
    a = fc.fit(data, n_sections=2, integrator=True, method="ipopt")
    b = fc.fit(data, n_sections=2, integrator=True, method="barrier-lm")
    w = np.logspace(-1, 2.5, 1000)
    ga, gb = a.model.frequency_response(w), b.model.frequency_response(w)
    assert np.max(np.abs(ga / gb - 1)) < 1e-6
    assert abs(a.model.delay - b.model.delay) < 1e-8


def test_derivative_paths_give_the_same_fit():
    """The numpy path of the dc gauge and CasADi's mapped AD: the same stages, the same
    model to rounding (both exact)."""
    _, data = two_section_data(n_points=120)
    a = fc.fit(data, n_sections=2, integrator=True)
    b = fc.fit(data, n_sections=2, integrator=True,
               loop=fc.LoopOptions(derivatives="casadi-map"))
    assert a.options.loop.derivatives is None and b.options.loop.derivatives == "casadi-map"
    assert len(a.stages) == len(b.stages)
    assert all(abs(sa.nit - sb.nit) <= 3 for sa, sb in zip(a.stages, b.stages))
    w = np.logspace(-1, 2.5, 500)
    ga, gb = a.model.frequency_response(w), b.model.frequency_response(w)
    assert np.max(np.abs(ga / gb - 1)) < 1e-9
    assert a.max_rel_error < 1e-6 and b.max_rel_error < 1e-6


def test_recovery_without_integrator_and_delay():
    beta = [0.0, 2.0, 1.0, 0.1, 3.0, 1.0, 0.2, 2.0]
    model = fc.RationalDelayModel(fc.Structure(1, False, False), beta)
    w = np.logspace(-1, 2, 100)
    res = fc.fit(w, model.frequency_response(w), n_sections=1, delay=False)
    assert res.model.delay == 0.0
    assert res.max_rel_error < 1e-8


def test_recovery_first_order_basis():
    beta = [0.0, 1.5, 0.5, 1.0, 0.1, 1.0, 0.02, 1.0, 0.01, 1.0]
    model = fc.RationalDelayModel(fc.Structure(2, False, False, "first-order"), beta)
    w = np.logspace(-2, 3, 150)
    res = fc.fit(w, model.frequency_response(w), n_sections=2, delay=False,
                 basis="first-order")
    assert res.max_rel_error < 1e-8
    _check_min_phase_stable(res.model)


def test_tol_stops_adding_sections():
    _, data = two_section_data()
    res = fc.fit(data, n_sections=6, integrator=True, tol=1e-6, start="sequential")
    assert res.model.n_sections <= 3
    assert res.max_rel_error < 1e-6


def test_example_a_prefix_is_stable_minimum_phase_and_beats_the_thesis():
    """Four sections of example A on its 500 points: already far below the thesis's
    order-34 error of 0.2549 on the first three modes' window, and feasible exactly."""
    data = fc.systems.G_A()
    res = fc.fit(data, n_sections=4, integrator=True)
    _check_min_phase_stable(res.model)
    assert res.max_rel_error < 1.0
    assert abs(res.model.delay - 0.01) < 0.005


def test_deterministic_model_json_in_process_and_across_processes(tmp_path):
    _, data = two_section_data(n_points=80)
    a = fc.fit(data, n_sections=2, integrator=True).model.to_json()
    b = fc.fit(data, n_sections=2, integrator=True).model.to_json()
    assert a == b
    code = ("import numpy as np, freqid_casadi as fc\n"
            f"beta = {TRUE_BETA!r}\n"
            "m = fc.RationalDelayModel(fc.Structure(2, True, True), beta)\n"
            "w = np.logspace(-1, 2.5, 80)\n"
            "d = fc.FrequencyData(w, m.frequency_response(w), 'two-section')\n"
            "print(fc.fit(d, n_sections=2, integrator=True).model.to_json())\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert json.loads(out) == json.loads(a)
    assert out.strip() == a


def test_progress_callback_gets_every_stage():
    _, data = two_section_data(n_points=80)
    seen = []
    res = fc.fit(data, n_sections=2, integrator=True, progress=seen.append,
                 start="sequential")         # (one start: every record is kept)
    assert seen == list(res.stages)


def test_progress_lines_writes_one_line_per_stage(capsys):
    _, data = two_section_data(n_points=80)
    res = fc.fit(data, n_sections=2, integrator=True, progress="lines", start="sequential")
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == len(res.stages)
    assert "max rel. error" in err[-1]


def test_progress_true_is_silent_off_a_terminal(capsys):
    _, data = two_section_data(n_points=80)
    fc.fit(data, n_sections=2, integrator=True, progress=True)     # well within 30 s
    assert capsys.readouterr().err == ""


def test_progress_true_off_a_terminal_writes_a_line_per_heartbeat(monkeypatch, capsys):
    # a long run in a log file or a pipe shows it is alive: the latest record's line, with
    # the time elapsed, once HEARTBEAT seconds have passed since the start or the last line
    from freqid_casadi import _progress

    clock = iter([0.0, 10.0, 31.0, 40.0, 62.0, 3700.0])          # start, then one per record
    monkeypatch.setattr(_progress.time, "monotonic", lambda: next(clock))
    with _progress.channel(True, lambda r: f"record {r}") as emit:
        for record in range(5):
            emit(record)
    assert capsys.readouterr().err.splitlines() == [
        "[31 s] record 1", "[1 min 02 s] record 3", "[1 h 01 min] record 4"]


def test_progress_true_draws_a_bar_on_a_terminal(monkeypatch, capsys):
    import sys

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    _, data = two_section_data(n_points=80)
    for start in ("best", "sequential"):       # a fit of 0.1 s shows its records too
        res = fc.fit(data, n_sections=2, integrator=True, progress=True, start=start)
        err = capsys.readouterr().err
        assert "max rel. error" in err and "stage/s" in err       # tqdm's counter and rate
        assert err.count("max rel. error") >= len(res.stages) >= 2   # each record drawn
        assert "User_Requested_Stop" not in err


@pytest.mark.parametrize("bad", ["yes", 2, 0.5, [True]])
def test_progress_refuses_other_values(bad):
    _, data = two_section_data(n_points=40)
    with pytest.raises(fc.OptionError, match="progress must be True, False, 'lines' or a "
                       "callable"):
        fc.fit(data, n_sections=1, progress=bad)


def test_returned_beta_is_exactly_feasible_for_light_damping():
    """A lightly damped mode (zeta = 1e-4) is recovered, not pushed off its bound by IPOPT
    (no bound relaxation): the fitted dampings equal the true ones."""
    beta = [0.0, 1.0, 1.0, 2e-4, 9.0, 1.0, 1e-4, 10.0]
    model = fc.RationalDelayModel(fc.Structure(1, False, True), beta)
    w = np.logspace(0, 1.5, 200)
    res = fc.fit(w, model.frequency_response(w), n_sections=1)
    a, zn, wn, b, zd, wd = res.model.sections()[0]
    assert zn / np.sqrt(a) == pytest.approx(2e-4, rel=1e-5)
    assert zd / np.sqrt(b) == pytest.approx(1e-4, rel=1e-5)
    assert res.max_rel_error < 1e-6


@pytest.mark.parametrize("kwargs, exc, match", [
    ({"n_sections": 0}, StructureError, "n_sections must be >= 1"),
    ({"n_sections": -2}, StructureError, "n_sections must be >= 1"),
    ({"n_sections": 1.5}, StructureError, "positive integer"),
    ({"n_sections": True}, StructureError, "positive integer"),
    ({"n_sections": 1, "method": "newton"}, OptionError, "unknown method 'newton'"),
    ({"n_sections": 1, "basis": "third"}, OptionError, "unknown basis"),
    ({"n_sections": 1, "tol": -1.0}, OptionError, "tol must be a number > 0"),
    ({"n_sections": 1, "tol": float("nan")}, OptionError, "tol must be"),
    ({"n_sections": 40}, DataError, "too few data points"),
    ({"n_sections": 1, "loop": {"gauge": "b1"}}, OptionError, "loop must be a LoopOptions"),
    ({"n_sections": 1, "method": fc.LoopOptions()}, OptionError, "unknown method"),
])
def test_bad_options_raise_typed_errors(kwargs, exc, match):
    _, data = two_section_data(n_points=60)
    with pytest.raises(exc, match=match):
        fc.fit(data, **kwargs)


def test_bad_data_through_fit():
    w = np.logspace(0, 1, 20)
    with pytest.raises(DataError, match="response is missing"):
        fc.fit(w, n_sections=1)
    with pytest.raises(DataError, match="strictly increasing"):
        fc.fit(w[::-1], np.ones(20), n_sections=1)
    with pytest.raises(DataError, match="finite"):
        fc.fit(w, np.r_[np.ones(19), np.nan], n_sections=1)
    _, data = two_section_data(n_points=30)
    with pytest.raises(DataError, match="either a FrequencyData"):
        fc.fit(data, np.ones(30), n_sections=1)


@pytest.mark.slow
def test_noisy_fit_is_not_returned_silently():
    """2 % complex noise on example A at the thesis's order: near-cancelling pairs narrower
    than the frequency spacing are reported (FitResult.resolution and a warning) when the
    resolution guard is off; by default the guard keeps the floored fit, which is
    resolved (tests/test_guard.py)."""
    from freqid_casadi.errors import ResolutionWarning

    rng = np.random.default_rng(0)
    data = fc.systems.G_A()
    noise = 0.02 * (rng.standard_normal(500) + 1j * rng.standard_normal(500)) / np.sqrt(2)
    noisy = fc.FrequencyData(data.omega, data.response * (1 + noise), "noisy A")
    with pytest.warns(ResolutionWarning, match="spacing: features between the samples that "
                      "the noisy data do not determine.*min_damping='auto'"):
        res = fc.fit(noisy, n_sections=17, integrator=True,
                     loop=fc.LoopOptions(resolution_guard=False))
    assert not res.resolution.ok and len(res.resolution.flags) >= 1
    guarded = fc.fit(noisy, n_sections=17, integrator=True)
    assert guarded.resolution.ok and guarded.details["resolution_guard"]["kept"] == "floored"


@pytest.mark.parametrize("rms, ratio, success, says, not_says", [
    (1e-13, 0.9, True, "the fit is exact to rounding, so these are spare sections",
     "min_damping"),
    (2e-3, 1.1, False, "the noisy data do not determine (the residual is at the noise: "
     "RMS 1.1 times it)", "exact to rounding"),
    (2e-3, 30.0, False, "residual that is not noise (RMS 30 times the noise its point-to-"
     "point differences show): the fit stopped on its way", "noisy data"),
    (2e-3, 30.0, True, "the fit misses something", "final_max_iter"),
    (2e-3, float("nan"), False, "(no noise level could be estimated)", "noisy data")])
def test_resolution_warning_names_the_cause(rms, ratio, success, says, not_says):
    """A failed resolution check's advice follows what the residual says. Exact to
    rounding (RMS <= ROUNDING_RMS = 1e-8; example A at 17 sections on a machine without
    AVX-512 puts a spare pole 0.06 rad/s from an antiresonance): spare sections, which a
    damping floor does not remove. At the noise (RMS at most twice the point-to-point
    noise): features the noisy data do not determine. Neither (barrier-LM on example C
    stopped at RMS 1e-9 of exact data, which the warning called "typical of noisy data"):
    sections the fit has not placed, with "continue the fit" when it did not converge."""
    from types import SimpleNamespace

    from freqid_casadi.core.resolution import ResolutionCheck
    from freqid_casadi.errors import ResolutionWarning
    from freqid_casadi.fitting.fit import _warn_unresolved

    check = ResolutionCheck(ok=False, flags=(None,), narrow=(), n_sections=3, factor=1.0)
    result = SimpleNamespace(resolution=check, rms_rel_error=rms, success=success,
                             details={"noise": {"ratio": ratio, "consistent": ratio <= 2}})
    with pytest.warns(ResolutionWarning) as caught:
        _warn_unresolved(result, 2)
    text = str(caught[0].message)
    assert text.startswith("the model has 1 near-cancelling pole/zero pair(s)")
    assert says in text and not_says not in text
    assert ("continue the fit (a higher final_max_iter)" in text) == (
        not ratio <= 2 and not success)
    # a floor the user gave is not advised again (a resonator's S21 fitted with
    # min_damping='auto' was told to refit with min_damping='auto')
    given = SimpleNamespace(**vars(result), options=SimpleNamespace(min_damping="auto"),
                            zeta_min=1.2e-4)
    with pytest.warns(ResolutionWarning) as caught:
        _warn_unresolved(given, 2)
    text = str(caught[0].message)
    assert "refit with min_damping='auto'" not in text and "min_damping='auto')" not in text
    if ratio <= 2 and rms > 1e-8:
        assert ("the damping floor given (zeta >= 0.00012) follows the median spacing, "
                "wider than the spacing there") in text


@pytest.mark.parametrize("fixed", [None, {"delay": 0.0}])
def test_one_resolution_warning_at_the_callers_line(monkeypatch, fixed):
    """A fit whose resolution check fails warns once, for the fit it returns, at the
    caller's line (the warnings filter's "default" action shows each line once), with a
    fixed parameter too (its fit is composed after the inner fits, which stay quiet)."""
    import freqid_casadi.fitting.fit as fit_module
    from freqid_casadi.core.resolution import ResolutionCheck
    from freqid_casadi.errors import ResolutionWarning

    failed = ResolutionCheck(ok=False, flags=(None,), narrow=(), n_sections=2, factor=1.0)
    monkeypatch.setattr(fit_module, "check_resolution", lambda model, omega: failed)
    _, data = two_section_data(n_points=100)
    with pytest.warns(ResolutionWarning) as caught:
        res = fc.fit(data, n_sections=2, integrator=True, fixed=fixed,
                     loop=fc.LoopOptions(resolution_guard=False))
    assert res.resolution is failed
    assert len(caught) == 1 and caught[0].filename == __file__


def test_clean_fit_passes_the_resolution_check():
    _, data = two_section_data(n_points=100)
    res = fc.fit(data, n_sections=2, integrator=True)
    assert res.resolution.ok


def _noisy_a(seed=0):
    rng = np.random.default_rng(seed)
    data = fc.systems.G_A()
    noise = 0.02 * (rng.standard_normal(500) + 1j * rng.standard_normal(500)) / np.sqrt(2)
    return data, fc.FrequencyData(data.omega, data.response * (1 + noise), "noisy A"), noise


@pytest.mark.slow
def test_damping_floor_keeps_a_noisy_fit_right_between_the_samples():
    """2 % complex noise on example A at the thesis's order (17 sections) with
    min_damping='auto': against the clean system, RMS below the noise RMS and max below the
    largest noise sample, at the samples and on a 10x denser grid (without the floor the
    dense-grid max is ~0.4, see results/noisy), and no pole or zero narrower than the
    spacing (no warning)."""
    import warnings

    from freqid_casadi.errors import ResolutionWarning
    from freqid_casadi.fitting.validation import dense_grid

    clean, noisy, noise = _noisy_a()
    with warnings.catch_warnings():
        warnings.simplefilter("error", ResolutionWarning)
        res = fc.fit(noisy, n_sections=17, integrator=True, min_damping="auto")
    from freqid_casadi.fitting.fit import resolution_damping

    zeta_min = resolution_damping(noisy.omega)
    assert res.zeta_min == zeta_min == pytest.approx(0.01167, rel=1e-3)
    assert res.resolution.ok
    s = res.model.sections()
    assert np.all(s[:, 1] / np.sqrt(np.maximum(s[:, 0], 1e-300)) >= zeta_min * (1 - 1e-9))
    assert np.all(s[:, 4] / np.sqrt(s[:, 3]) >= zeta_min * (1 - 1e-9))
    dense = dense_grid(clean.omega, 10)
    e_s = np.abs(clean.response / res.model.frequency_response(clean.omega) - 1)
    e_d = np.abs(fc.systems.G_A(omega=dense).response / res.model.frequency_response(dense) - 1)
    noise_rms, noise_max = np.sqrt(np.mean(np.abs(noise) ** 2)), np.max(np.abs(noise))
    for e in (e_s, e_d):
        assert np.sqrt(np.mean(e ** 2)) < noise_rms / 2
        assert np.max(e) < noise_max
    _check_min_phase_stable(res.model)


def test_damping_floor_is_exact_and_costs_little_on_clean_data():
    """A lightly damped true mode (zeta = 2e-3) under a floor of 0.01: every pole and zero
    of the fit has zeta >= 0.01 exactly; the fit stays stable and minimum phase."""
    beta = [0.0, 1.0, 1.0, 0.05, 3.0, 1.0, 0.002, 10.0]
    model = fc.RationalDelayModel(fc.Structure(1, False, True), beta)
    w = np.logspace(0, 1.5, 200)
    res = fc.fit(w, model.frequency_response(w), n_sections=2, min_damping=0.01)
    s = res.model.sections()
    zeta = np.r_[s[:, 1] / np.sqrt(s[:, 0]), s[:, 4] / np.sqrt(s[:, 3])]
    assert np.all(zeta >= 0.01)
    assert res.zeta_min == 0.01 and res.options.min_damping == 0.01
    _check_min_phase_stable(res.model)
    free = fc.fit(w, model.frequency_response(w), n_sections=2)
    assert free.max_rel_error < 1e-6 < res.max_rel_error < 1.0


@pytest.mark.parametrize("kwargs, match", [
    ({"min_damping": "yes"}, "unknown min_damping"),
    ({"min_damping": -0.1}, r"min_damping must be None, 'auto' or a number in \[0, 1\)"),
    ({"min_damping": True}, "min_damping must be"),
    ({"min_damping": "auto", "method": "barrier-lm"}, "needs method='ipopt'"),
    ({"min_damping": "auto", "loop": fc.LoopOptions(gauge="b1")}, "needs gauge='dc'"),
    ({"min_damping": 0.01, "basis": "first-order"}, "needs gauge='dc'"),
])
def test_bad_min_damping(kwargs, match):
    _, data = two_section_data(n_points=60)
    with pytest.raises(OptionError, match=match):
        fc.fit(data, n_sections=1, **kwargs)

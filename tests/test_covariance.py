"""Tests of the parameter uncertainty (freqid_casadi.uncertainty.covariance, bands,
plots_uncertainty, _physical) and of scripts/uncertainty_calibration.py.

The system is the script's: 2 modes (5 Hz / zeta 0.02, 17 Hz / zeta 0.03), zero pairs at 60
and 300 rad/s, delay 5 ms, DC gain 1, on 400 points over 2..600 rad/s with 1 % complex noise.
"""

import dataclasses
import importlib.util
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

import freqid_casadi as fc  # noqa: E402
from freqid_casadi.fitting.bootstrap import bootstrap
from freqid_casadi.core import physical as _physical  # noqa: E402
from freqid_casadi.uncertainty import bands  # noqa: E402
from freqid_casadi.uncertainty import covariance  # noqa: E402
from freqid_casadi.plots import uncertainty as plots_uncertainty  # noqa: E402
from freqid_casadi.core.data import FrequencyData  # noqa: E402
from freqid_casadi.errors import DataError, OptionError, StructureError  # noqa: E402
from freqid_casadi.experiment import FrfEstimate  # noqa: E402
from freqid_casadi.fitting.fit import fit  # noqa: E402
from freqid_casadi.core.model import RationalDelayModel, Structure  # noqa: E402

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "uncertainty_calibration.py"


def _script():
    spec = importlib.util.spec_from_file_location("uncertainty_calibration_script", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


S = _script()


@pytest.fixture(scope="module")
def fitted():
    data = S.noisy_data(0)
    return fit(data, n_sections=2, start="rational")


@pytest.fixture(scope="module")
def unc(fitted):
    return covariance.parameter_uncertainty(fitted)


# ------------------------------------------------------------------ parametrization
MODELS = {
    "two quadratics": S.truth_model(),
    # numerator of section 1 first order (a = 0), section 2 with an undamped zero pair
    "degenerate": RationalDelayModel(Structure(2), [0.002, 3.0, 0, 0.7, 40.0, 2.0, 0.1, 10.0,
                                                    0.5, 0.0, 80.0, 1.0, 0.05, 30.0]),
    "integrator": RationalDelayModel(Structure(1, integrator=True),
                                     [0.01, 2.0, 1.0, 0.3, 50.0, 1.0, 0.02, 20.0]),
    "first-order basis": RationalDelayModel(Structure(2, basis="first-order"),
                                            [0.001, 1.5, 1.0, 5.0, 2.0, 3.0, 0.0, 7.0, 1.0,
                                             70.0]),
    "no delay": RationalDelayModel(Structure(1, delay=False),
                                   [0.0, 1.0, 1.0, 0.2, 30.0, 1.0, 0.05, 10.0]),
}
OMEGA = np.logspace(-0.5, 2.7, 120)


@pytest.mark.parametrize("name", list(MODELS))
def test_physical_parameters_reproduce_the_response(name):
    model = MODELS[name]
    par = _physical.parametrize(model)
    log_g, _ = _physical.log_response(par, par.theta, OMEGA)
    g = model.frequency_response(OMEGA)
    np.testing.assert_allclose(np.exp(log_g), g, rtol=1e-12)
    back = _physical.to_model(par, par.theta).frequency_response(OMEGA)
    np.testing.assert_allclose(back, g, rtol=1e-12)


@pytest.mark.parametrize("name", list(MODELS))
def test_analytic_derivatives_match_central_differences(name):
    """d ln G_N / d theta (analytic) against central differences of the model's own
    frequency_response (RationalDelayModel built from the perturbed parameters)."""
    par = _physical.parametrize(MODELS[name])
    _, jac = _physical.log_response(par, par.theta, OMEGA)
    for i in np.flatnonzero(~par.at_bound):
        step = 1e-6 * max(abs(par.theta[i]), 1e-3)
        tp, tm = np.array(par.theta), np.array(par.theta)
        tp[i] += step
        tm[i] -= step
        gp = _physical.to_model(par, tp).frequency_response(OMEGA)
        gm = _physical.to_model(par, tm).frequency_response(OMEGA)
        fd = np.log(gp / gm) / (2 * step)
        err = np.max(np.abs(fd - jac[:, i])) / np.max(np.abs(jac[:, i]))
        assert err < 1e-6, f"{par.names[i]}: relative derivative error {err:.2e}"


def test_parameter_names_and_bounds_of_degenerate_model():
    par = _physical.parametrize(MODELS["degenerate"], OMEGA[-1])
    assert par.names == ("delay", "log_gain", "root_num[1]", "s2_num[1]", "omega_den[1]",
                         "zeta_den[1]", "omega_num[2]", "zeta_num[2]", "omega_den[2]",
                         "zeta_den[2]")
    assert list(np.flatnonzero(par.at_bound)) == [3, 7]      # missing s^2, zeta_num = 0
    # first-order numerator 2 zn wn s + wn^2 = 56 s + 1600: root 1600/56 rad/s
    assert par.theta[2] == pytest.approx(1600 / 56)
    # denominator 2 s^2 + 2 s + 100: omega = sqrt(50), zeta = 2 / (2 sqrt(200))
    assert par.theta[4] == pytest.approx(np.sqrt(50))
    assert par.theta[5] == pytest.approx(1 / np.sqrt(200))


def test_zero_section_is_a_structure_error():
    # refused where the model is built (it reached _physical.parametrize before)
    with pytest.raises(StructureError, match="zero numerator"):
        RationalDelayModel(Structure(1), [0.0, 1.0, 0, 0, 0, 1, 0.1, 5.0])


# ------------------------------------------------------------------ delta method
def test_record_fields_and_noise_from_residuals(fitted, unc):
    assert unc.noise_source == "residuals" and unc.method == "delta"
    assert unc.param_names[:2] == ("delay", "log_gain")
    assert unc.covariance.shape == (10, 10) and not unc.at_bound.any()
    # 1 % complex noise: each real component of the relative residual has variance 5e-5
    assert unc.sigma2 == pytest.approx(5e-5, rel=0.1)
    assert unc.dof == 2 * 400 - 10
    assert [round(m.frequency_hz, 2) for m in unc.modes] == [5.0, 17.0]
    assert unc.delay == fitted.model.delay and unc.delay_std == unc.std_of("delay")
    assert unc.gain == pytest.approx(1.0, rel=2e-3)
    assert unc.gain_std == pytest.approx(unc.gain * unc.std_of("log_gain"))
    assert np.allclose(unc.covariance, unc.covariance.T)
    assert np.all(np.linalg.eigvalsh(unc.covariance) > 0)
    lo, hi = unc.interval("delay")
    assert lo < 0.005 < hi
    lo_t, hi_t = unc.interval("delay", dist="t")
    assert hi_t - lo_t > hi - lo


def test_to_dict_is_json(unc):
    import json

    d = json.loads(json.dumps(covariance.ParameterUncertainty.to_dict(unc)))
    assert d["param_names"] == list(unc.param_names)
    np.testing.assert_array_equal(np.array(d["covariance"], float), unc.covariance)


@pytest.mark.parametrize("name", ["integrator", "first-order basis", "no delay"])
def test_weighted_calibration_with_local_refits(name):
    """Heteroscedastic noise (relative RMS 0.3 % .. 3 % over the band), fitted with
    w = 1/sigma_i^2 (normalised to mean 1): 300 replicates refitted locally from the truth
    (least squares in the physical parameters). The reported stds, noise from the
    weighted residuals, match the empirical ones within 20 %, and 95 % intervals cover."""
    model = MODELS[name]
    par = _physical.parametrize(model)
    g = model.frequency_response(OMEGA)
    sigma = np.geomspace(0.003, 0.03, OMEGA.size)
    w = 1 / sigma ** 2
    w /= w.mean()
    rng = np.random.default_rng(11)
    est, std = [], []
    for _ in range(300):
        n = (rng.standard_normal(OMEGA.size) + 1j * rng.standard_normal(OMEGA.size)) / np.sqrt(2)
        phi = g * (1 + sigma * n)
        theta, ok = _physical.polish(par, OMEGA, phi, w)
        assert ok
        u = covariance.parameter_uncertainty(_physical.to_model(par, theta),
                                             FrequencyData(OMEGA, phi, weights=w))
        est.append(theta)
        std.append(u.std)
    est, std = np.array(est), np.array(std)
    free = ~par.at_bound
    ratio = std[:, free].mean(axis=0) / est[:, free].std(axis=0, ddof=1)
    cover = np.mean(np.abs(est - par.theta)[:, free] <= 1.96 * std[:, free], axis=0)
    assert np.all(np.abs(ratio - 1) < 0.2), ratio
    assert np.all((cover > 0.9) & (cover < 0.99)), cover


def test_given_variance_matches_the_residual_estimate(fitted, unc):
    """With the true noise variance E|Phi - G|^2 = 1e-4 |G|^2 the sandwich gives the same
    stds as the residual estimate, scaled by sqrt(5e-5 / sigma2)."""
    g = S.truth_model().frequency_response(fitted.data.omega)
    given = covariance.parameter_uncertainty(fitted, noise_variance=1e-4 * np.abs(g) ** 2)
    assert given.noise_source == "given"
    np.testing.assert_allclose(given.std, unc.std * np.sqrt(5e-5 / unc.sigma2), rtol=0.02)
    est = FrfEstimate(fitted.data, variance=1e-4 * np.abs(g) ** 2)
    from_data = covariance.parameter_uncertainty(fitted.model, est)
    assert from_data.noise_source == "data"
    np.testing.assert_allclose(from_data.std, given.std, rtol=1e-12)


def test_parameters_at_bound_are_reported_not_known():
    model = MODELS["degenerate"]
    rng = np.random.default_rng(3)
    g = model.frequency_response(OMEGA)
    data = FrequencyData(OMEGA, g * (1 + 0.01 * (rng.standard_normal(OMEGA.size)
                                                 + 1j * rng.standard_normal(OMEGA.size))))
    u = covariance.parameter_uncertainty(model, data)
    bound = np.array(u.at_bound)
    assert list(np.flatnonzero(bound)) == [3, 7]
    assert np.all(np.isnan(u.std[bound])) and np.all(np.isfinite(u.std[~bound]))
    assert np.all(np.isnan(u.covariance[bound])) and np.all(np.isnan(u.covariance[:, bound]))
    assert u.dof == 2 * OMEGA.size - 8
    zero_delay = RationalDelayModel(Structure(1), [0.0, 1.0, 1.0, 0.3, 50.0, 1.0, 0.02, 20.0])
    u0 = covariance.parameter_uncertainty(zero_delay, FrequencyData(
        OMEGA, zero_delay.frequency_response(OMEGA) * (1 + 1e-3j)))
    assert u0.at_bound[0] and np.isnan(u0.delay_std)


def test_damping_floor_of_the_fit_is_a_bound(fitted, unc):
    """A fit with min_damping: a damping at the floor is at its bound (std NaN)."""
    k = unc.modes[0].section
    zeta = float(fitted.model.sections()[k - 1][4])
    res = dataclasses.replace(fitted, zeta_min=zeta)        # the floor the fit used
    u = covariance.parameter_uncertainty(res)
    assert u.at_bound[u.param_names.index(f"zeta_den[{k}]")]
    assert u.modes[0].zeta_at_bound and np.isnan(u.modes[0].zeta_std)
    assert np.isfinite(u.modes[0].omega_n_std)
    assert "0.02 (at bound)" in plots_uncertainty.render_markdown(u)


def test_bad_input(fitted, unc):
    with pytest.raises(DataError, match="data must be a FrequencyData"):
        covariance.parameter_uncertainty(fitted.model)
    with pytest.raises(StructureError, match="RationalDelayModel"):
        covariance.parameter_uncertainty("model", fitted.data)
    with pytest.raises(DataError, match="noise_variance"):
        covariance.parameter_uncertainty(fitted, noise_variance=-1.0)
    with pytest.raises(DataError, match="cannot determine"):
        covariance.parameter_uncertainty(fitted.model, FrequencyData(
            fitted.data.omega[:4], fitted.data.response[:4]))
    with pytest.raises(OptionError, match="level"):
        unc.interval("delay", level=1.5)
    with pytest.raises(OptionError, match="unknown parameter"):
        unc.std_of("omega_n")
    with pytest.raises(OptionError, match="n_boot"):
        bootstrap(fitted, n_boot=1)
    with pytest.raises(OptionError, match="refit"):
        bootstrap(fitted, refit="global")


def test_with_std_fills_modal_records(unc):
    @dataclasses.dataclass(frozen=True)
    class Mode:                      # the fields of freqid_casadi.core.modes.Mode used here
        omega_n: float
        zeta: float
        omega_n_std: float = float("nan")
        zeta_std: float = float("nan")

    recs = [Mode(m.omega_n * (1 + 1e-9), m.zeta) for m in unc.modes] + [Mode(5.0, 0.5)]
    out = covariance.with_std(recs, unc)
    assert [r.omega_n_std for r in out[:2]] == [m.omega_n_std for m in unc.modes]
    assert [r.zeta_std for r in out[:2]] == [m.zeta_std for m in unc.modes]
    assert out[2] is recs[2]


# ------------------------------------------------------------------ bootstrap
def test_bootstrap_agrees_with_delta_and_ignores_n_jobs(fitted, unc):
    b1 = bootstrap(fitted, n_boot=200, seed=1)
    assert b1.method == "bootstrap" and b1.noise_source == "bootstrap"
    assert b1.samples.shape == (200, 10)
    ratio = unc.std / b1.std
    # measured 0.93 .. 1.24 (log_gain), 200 replicates: 5 % sampling error of a std
    assert np.all((ratio > 0.75) & (ratio < 1.35)), ratio
    b2 = bootstrap(fitted, n_boot=6, seed=1, n_jobs=2)
    np.testing.assert_array_equal(b2.samples, b1.samples[:6])


def test_bootstrap_with_fit_refits_matches_sections(fitted, unc):
    b = bootstrap(fitted, n_boot=12, seed=2, refit="fit")
    assert np.all(np.isfinite(b.samples))
    # refits of the same data order their sections by their own rules: matched by
    # frequency, every sample is near the model (within 6 delta-method stds)
    dev = np.abs(b.samples - unc.values) / unc.std
    assert dev.max() < 6


# ------------------------------------------------------------------ bands
def test_band_matches_sampled_parameters(unc):
    """The delta-method variance of ln|G_N| and of the phase equals that of models drawn
    from N(theta, C) (linear regime at 1 % noise), within the sampling error."""
    omega = np.array([10.0, 31.4, 60.0, 106.8, 400.0])
    band = bands.response_band(unc, omega)
    par = _physical.parametrize(unc.model)
    rng = np.random.default_rng(0)
    draws = rng.multivariate_normal(unc.values, unc.covariance, size=4000)
    logs = np.array([_physical.log_response(par, t, omega)[0] for t in draws])
    base = _physical.log_response(par, unc.values, omega)[0]
    d = logs - base
    d.imag = (d.imag + np.pi) % (2 * np.pi) - np.pi
    z = 1.959964
    np.testing.assert_allclose(np.log(band.magnitude_upper / band.magnitude) / z,
                               d.real.std(axis=0), rtol=0.08)
    np.testing.assert_allclose((band.phase_upper - band.phase) / z, d.imag.std(axis=0),
                               rtol=0.08)
    assert np.all(band.magnitude_lower < band.magnitude)


def test_band_on_data_and_weight_covers_it(fitted, unc):
    band = bands.response_band(unc, data=fitted.data)
    np.testing.assert_allclose(band.rel_error, fitted.rel_error, rtol=1e-9)
    assert np.all(band.rel_error_upper > band.rel_error)
    w = bands.fit_band_weight(unc, fitted.data, k=2.0, order=2)
    upper = band.rel_error + 2.0 * band.rel_error_std
    assert np.all(w.magnitude >= upper * (1 - 1e-9))
    with pytest.raises(OptionError, match="k must be"):
        bands.fit_band_weight(unc, fitted.data, k=-1)


def test_plots_and_markdown(fitted, unc):
    from matplotlib.figure import Figure

    fig = plots_uncertainty.bode_band(unc, fitted.data)
    assert isinstance(fig, Figure) and len(fig.axes) == 2
    assert len(fig.axes[0].collections) >= 1            # the band
    fig2 = plots_uncertainty.rel_error_band(unc, fitted.data, title="x")
    assert isinstance(fig2, Figure) and fig2.axes[0].get_yscale() == "log"
    from freqid_casadi import plots

    fig3 = plots_uncertainty.rel_error_band(unc, fitted.data, fig=plots.relative_error(fitted))
    assert fig3.axes[0].get_legend_handles_labels()[1][-1].startswith("model spread")
    import matplotlib.pyplot as plt

    plt.close("all")
    md = plots_uncertainty.render_markdown(unc)
    assert md.count("±") >= 8 and "| 1 |" in md and "| 2 |" in md and "residuals" in md
    assert "at bound" not in md


def test_a_band_the_data_do_not_determine_keeps_the_axes_of_the_curves():
    # an undamped pole gives a band of thousands of dB (a WaveForms export: +-3.4e3 dB),
    # which flattened the data to a line: the axes keep the curves' range, widened by at
    # most a quarter of its span each side, and say when the band goes beyond them
    from matplotlib.figure import Figure

    ax = Figure().subplots()
    w = np.geomspace(1, 100, 50)
    ax.semilogx(w, np.linspace(0.0, 10.0, 50))
    lo, hi = ax.get_ylim()                                       # 0..10 with matplotlib's margin
    cut = plots_uncertainty._within(ax, np.full(50, -3000.0), np.full(50, 3000.0))
    assert cut and ax.get_ylim() == pytest.approx((lo - 0.25 * (hi - lo), hi + 0.25 * (hi - lo)))
    ax2 = Figure().subplots()
    ax2.semilogx(w, np.linspace(0.0, 10.0, 50))
    cut = plots_uncertainty._within(ax2, np.linspace(-1.0, 9.0, 50), np.linspace(1.0, 11.5, 50))
    assert not cut and ax2.get_ylim() == pytest.approx((-1.0, 11.5))


# ------------------------------------------------------------------ calibration
@pytest.mark.slow
def test_monte_carlo_calibration():
    """200 replicates (seeds 5000.., independent of the report's 0..999), each refitted
    with fit(n_sections=2, start="rational"): coverage of the 95 % intervals of both
    natural frequencies, dampings and the delay, and the mean reported std over the
    empirical one. Measured: coverage 0.940-0.980, ratios 0.99-1.16 (omega_2: its
    empirical std is low in this draw; 1000 replicates give 0.998, results/uncertainty).
    Bounds: ratio within 20 %; coverage 92-98 % widened by about 1.3 binomial standard
    errors (1.5 points at 200 replicates) to 90-99 %. About 65-190 s with 2 workers on
    the loaded 2-core machine (its time is not a test: scripts/uncertainty_calibration.py
    reports it)."""
    val, std, _ = S.monte_carlo(200, jobs=2, first_seed=5000)
    summary = S.summarize(val, std)
    assert summary["n_valid"] == 200
    for name in ("omega_1", "zeta_1", "omega_2", "zeta_2", "delay"):
        p = summary["parameters"][name]
        assert 0.90 <= p["coverage"] <= 0.99, (name, p)
        assert 0.8 <= p["std_ratio"] <= 1.2, (name, p)


def test_fit_result_uncertainty_is_the_delta_method_record(fitted):
    u = fitted.uncertainty
    assert u is fitted.uncertainty                       # computed once
    ref = covariance.parameter_uncertainty(fitted)
    assert np.array_equal(u.covariance, ref.covariance, equal_nan=True)
    assert u.delay_std > 0 and u.gain_std > 0 and u.noise_source == "residuals"
    assert len(u.modes) == 2 and all(m.omega_n_std > 0 for m in u.modes)


def test_uncertainty_of_a_negative_gain_fit():
    w = np.logspace(0, 2, 200)
    s = 1j * w
    rng = np.random.default_rng(3)
    g = -4 / (s ** 2 + 2 * 0.05 * 10 * s + 100) * np.exp(-0.002 * s)
    g = g * (1 + 0.01 * (rng.standard_normal(w.size) + 1j * rng.standard_normal(w.size)))
    res = fc.fit(w, g, n_sections=1, start="rational")
    assert res.model.gain < 0
    u = res.uncertainty
    assert np.isfinite(u.gain_std) and 0 < u.gain_std < 0.1 * abs(u.gain)
    assert abs(u.modes[0].omega_n - 10) < 3 * u.modes[0].omega_n_std + 1e-3


def test_fit_report_figures_carry_the_bands(fitted):
    import matplotlib

    matplotlib.use("Agg")
    from freqid_casadi import plots
    from freqid_casadi.report import folder as report

    bode, rel = plots.bode(fitted), plots.relative_error(fitted)
    report._add_bands(fitted, bode, rel)
    labels = [t.get_text() for ax in bode.axes for leg in [ax.get_legend()] if leg
              for t in leg.get_texts()]
    assert any("95 % band" in t for t in labels)
    assert len(rel.axes[0].collections) >= 1               # the shaded upper band
    import matplotlib.pyplot as plt

    plt.close("all")


def test_a_fit_stopped_before_an_optimum_gets_no_band(fitted):
    """A not-converged fit's intervals do not apply (its parameters are "not determined",
    summary.md says why): its figures show the error and the response without a band (the
    C example's report drew one)."""
    import dataclasses

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from freqid_casadi import plots
    from freqid_casadi.report import folder as report

    stopped = dataclasses.replace(fitted, status=fc.FitStatus.NOT_CONVERGED, success=False)
    bode, rel = plots.bode(stopped), plots.relative_error(stopped)
    before = [len(ax.collections) for fig in (bode, rel) for ax in fig.axes]
    report._add_bands(stopped, bode, rel)
    assert [len(ax.collections) for fig in (bode, rel) for ax in fig.axes] == before
    plt.close("all")


def test_an_exactly_cancelling_section_is_undetermined_but_leaves_the_band_alone():
    """A model with a third, exactly cancelling section (pole = zero): the Jacobian has a
    numerically null direction (condition 1e16). Its parameters are undetermined (huge
    std); the response does not move along it, so the response band stays at the noise
    level (leverage <= 1). Inverting the null direction as well (the covariance itself)
    gives a relative std of 17 (measured), 1.7e7 times the noise."""
    w = np.logspace(-1, 2, 200)
    beta = [0.01, 2.0, 1, 0.05, 3.0, 1, 0.02, 30.0, 1, 0.1, 20.0, 1, 0.03, 12.0,
            1, 0.3, 5.0, 1, 0.3, 5.0]
    model = fc.RationalDelayModel(fc.Structure(3, False, True), beta)
    rng = np.random.default_rng(0)
    noise = rng.standard_normal(w.size) + 1j * rng.standard_normal(w.size)
    data = fc.FrequencyData(w, model.frequency_response(w) * (1 + 1e-6 * noise))
    unc = covariance.parameter_uncertainty(model, data)
    sigma = np.sqrt(unc.sigma2)                                    # measured 1.01e-6
    assert unc.condition_number > 1e14                             # measured 1.1e16
    assert unc.std_of("omega_num[3]") > 1e3 * 5.0                  # measured 8.8e8
    assert unc.std_of("omega_den[2]") < 1e-4 * 12.0                # the others: determined
    band = bands.response_band(unc, data=data)
    assert band.rel_std.max() <= 2 * sigma                         # measured 0.95 sigma
    assert band.rel_std.min() > 0                                  # sums of squares
    par = _physical.parametrize(model)
    free = ~unc.at_bound
    _, dlog = _physical.log_response(par, unc.values, w)
    g, cov = dlog[:, free], unc.covariance[np.ix_(free, free)]
    full = (np.einsum("ij,jk,ik->i", g.real, cov, g.real)
            + np.einsum("ij,jk,ik->i", g.imag, cov, g.imag))
    assert np.sqrt(np.abs(full)).max() > 1e3 * sigma               # measured 17


@pytest.mark.parametrize("given", [False, True])
def test_the_band_from_the_factor_equals_the_covariance_band_when_well_conditioned(given):
    """``response_factor`` (sums of squares) against ``covariance`` (quadratic form) on a
    well-conditioned 2-section fit, noise from the residuals or given."""
    w = np.logspace(-1, 2, 120)
    beta = [0.01, 2.0, 1, 0.05, 3.0, 1, 0.02, 30.0, 1, 0.1, 20.0, 1, 0.03, 12.0]
    model = fc.RationalDelayModel(fc.Structure(2, False, True), beta)
    g = model.frequency_response(w)
    rng = np.random.default_rng(1)
    data = fc.FrequencyData(w, g * (1 + 1e-3 * (rng.standard_normal(w.size)
                                                + 1j * rng.standard_normal(w.size))))
    kw = dict(noise_variance=np.full(w.size, 2e-6) * np.abs(g) ** 2) if given else {}
    unc = covariance.parameter_uncertainty(model, data, **kw)
    assert unc.condition_number < 1e6
    by_factor = bands.response_band(unc, data=data).rel_std
    by_cov = bands.response_band(dataclasses.replace(unc, response_factor=None),
                                 data=data).rel_std
    np.testing.assert_allclose(by_factor, by_cov, rtol=1e-9)
    np.testing.assert_allclose(unc.response_covariance, unc.covariance,
                               rtol=1e-6, atol=1e-12 * np.abs(unc.covariance).max())


def test_bootstrap_progress_receives_every_replicate():
    from freqid_casadi.fitting.bootstrap import bootstrap

    model = fc.RationalDelayModel(fc.Structure(1), [0.01, 2.0, 1.0, 0.3, 5.0, 1.0, 0.05, 3.0])
    w = np.logspace(-0.5, 1.5, 60)
    rng = np.random.default_rng(3)
    g = model.frequency_response(w) * (1 + 0.01 * rng.standard_normal(60))
    seen = []
    rec = bootstrap(model, fc.FrequencyData(w, g), n_boot=5, progress=seen.append)
    assert len(seen) == 5 and np.array_equal(np.array(seen), rec.samples)


def test_bartlett_pvalue_is_scipys():
    """local_variance's Bartlett test, written out: scipy.stats.bartlett's p-value bit
    for bit (measured on 2000 random sets of 2-8 blocks: all equal)."""
    from scipy import stats

    from freqid_casadi.uncertainty.covariance import _bartlett_pvalue

    rng = np.random.default_rng(3)
    for scales in ([1.0, 1.0, 1.0], [1.0, 1.5, 0.7, 2.0]):
        blocks = [s * rng.standard_normal(60) for s in scales]
        assert _bartlett_pvalue(blocks) == float(stats.bartlett(*blocks).pvalue)


def test_the_delay_diagnostic_and_the_uncertainty_table_give_one_std():
    # a binary UFF export fitted at 4 sections: the delay-undetermined record said 1.17 s,
    # the report's table 0.746 s (the record took the noise constant over the band, the
    # table its local level, as an "ok" fit's uncertainty does); one number now
    rng = np.random.default_rng(4)
    w = np.geomspace(1.0, 100.0, 200)
    s = 1j * w
    g = 3.0 / (s * s + 0.4 * s + 16.0) * (1 + 0.02 * (1 + w / 20) * (
        rng.standard_normal(w.size) + 1j * rng.standard_normal(w.size)))   # noise grows
    res = fc.fit(fc.FrequencyData(w, g), n_sections=2, integrator=False)
    (rec,) = [d for d in res.diagnostics if d.code == "delay-undetermined"] or [None]
    if rec is None or "delay_std" not in rec.values:
        pytest.skip(f"this draw's delay is determined (status {res.status})")
    # measured: 1379.49 against 1377.95 (SkylakeX kernel), 727.7 against 707.0 (Prescott:
    # the draw's fit differs; the table also holds parameters at the fit's bounds, and a
    # delay of std 1e3 s is ill-conditioned); before, with the constant noise level, 929
    # against 1378 (33 %). Bound: 10 %, three times the measured spread
    assert rec.values["delay_std"] == pytest.approx(res.uncertainty.delay_std, rel=0.1)

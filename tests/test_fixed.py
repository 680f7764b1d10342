"""fit(..., fixed={"delay": h, "dc_gain": k}): known parameters held exactly."""

import re
import warnings

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi import OptionError
from freqid_casadi.cli.app import build_parser, main

WN, ZETA, RES, DELAY = (2.0, 9.0), (0.05, 0.03), (1.0, 0.3), 0.02
OMEGA = np.logspace(-1, 1.7, 120)


def plant(omega, integrator=False, k=1.0):
    s = 1j * omega
    g = sum(r * w * w / (s * s + 2 * z * w * s + w * w) for w, z, r in zip(WN, ZETA, RES))
    g = k * np.exp(-DELAY * s) * g / sum(RES)                # G(0) = k (K0 = k with 1/s)
    return g / s if integrator else g


def low_frequency_gain(model):
    """K0 (integrator) or G(0): the gain times the sections' DC values."""
    sec = model.sections()
    return model.gain * float(np.prod(sec[:, 2] ** 2 / sec[:, 5] ** 2))


DATA = fc.FrequencyData(OMEGA, plant(OMEGA))


@pytest.fixture(scope="module")
def held_delay():
    return fc.fit(DATA, n_sections=2, fixed={"delay": 0.0123})


def test_fixed_delay_is_returned_exactly(held_delay):
    res = held_delay
    assert res.model.delay == 0.0123 and res.delay == 0.0123
    assert res.model.structure.delay and res.fixed == {"delay": 0.0123}
    assert "delay held at 0.0123" in res.message
    # the errors are those of the returned model on the user's data
    direct = np.abs(DATA.response / res.model.frequency_response(OMEGA) - 1)
    np.testing.assert_allclose(res.rel_error, direct, rtol=1e-12)
    assert res.data is not None and np.array_equal(res.data.response, DATA.response)
    # the true delay is 0.02: holding 0.0123 costs accuracy (measured max error 0.38)
    free = fc.fit(DATA, n_sections=2, fixed={"delay": DELAY})
    assert free.model.delay == DELAY and free.max_rel_error < 1e-6
    assert res.max_rel_error > 100 * free.max_rel_error


def test_fixed_delay_reported_as_fixed_by_the_covariance(held_delay):
    unc = held_delay.uncertainty
    i = unc.param_names.index("delay")
    assert unc.at_bound[i] and np.isnan(unc.std[i]) and np.isnan(unc.delay_std)
    assert unc.fixed == ("delay",) and unc.to_dict()["fixed"] == ["delay"]
    assert np.isfinite(unc.std[unc.param_names.index("log_gain")])


@pytest.mark.parametrize("integrator", [False, True])
def test_fixed_dc_gain_holds_the_low_frequency_gain(integrator):
    data = fc.FrequencyData(OMEGA, plant(OMEGA, integrator, k=4.4))
    res = fc.fit(data, n_sections=2, integrator=integrator, fixed={"dc_gain": 4.0})
    assert low_frequency_gain(res.model) == pytest.approx(4.0, rel=1e-12)
    w = 1e-7
    lf = res.model.rational_response(w) * ((1j * w) if integrator else 1.0)
    assert lf.real == pytest.approx(4.0, rel=1e-6)
    assert res.fixed == {"dc_gain": 4.0} and "dc_gain held at 4" in res.message
    unc = res.uncertainty
    assert unc.at_bound[unc.param_names.index("log_gain")] and "log_gain" in unc.fixed
    assert np.isnan(unc.gain_std)
    # the data's gain is 4.4: the rest of the model bends to the held 4 (measured 0.139)
    assert 0.05 < res.max_rel_error < 0.5


def test_fixed_both_and_negative_gain():
    data = fc.FrequencyData(OMEGA, -plant(OMEGA))
    res = fc.fit(data, n_sections=2, fixed={"delay": DELAY, "dc_gain": -1.0})
    assert res.model.delay == DELAY and res.model.structure.gain_sign == -1
    assert low_frequency_gain(res.model) == pytest.approx(-1.0, rel=1e-12)
    assert res.max_rel_error < 1e-5            # both are the true values


@pytest.mark.parametrize("kwargs, match", [
    ({"fixed": {"gain": 1.0}}, "allowed keys: delay, dc_gain"),
    ({"fixed": {"delay": "0.1"}}, "finite real number"),
    ({"fixed": {"delay": float("nan")}}, "finite real number"),
    ({"fixed": {"delay": True}}, "finite real number"),
    ({"fixed": {"delay": -0.1}}, ">= 0"),
    ({"fixed": {"dc_gain": 0.0}}, "nonzero"),
    ({"fixed": [("delay", 0.1)]}, "allowed keys"),
    ({"fixed": {"delay": 0.1}, "delay": False}, "delay=False"),
    ({"fixed": {"dc_gain": -2.0}, "gain_sign": "positive"}, "gain_sign"),
])
def test_fixed_bad_values(kwargs, match):
    with pytest.raises(OptionError, match=match):
        fc.fit(DATA, n_sections=1, **kwargs)


def test_cli_fix(tmp_path, capsys):
    args = build_parser().parse_args(["fit", "x.csv", "--sections", "2", "--out", "o",
                                      "--fix", "delay=0.0123", "--fix", "dc_gain=4"])
    assert dict(args.fix) == {"delay": 0.0123, "dc_gain": 4.0}
    assert main(["fit", "x.csv", "--sections", "2", "--out", str(tmp_path / "o"),
                 "--fix", "gain=2"]) == 2
    err = capsys.readouterr().err
    assert "--fix" in err and "delay, dc_gain" in err
    path = tmp_path / "frf.csv"
    fc.save_csv(DATA, path)
    assert main(["fit", str(path), "--sections", "2", "--out", str(tmp_path / "r"),
                 "--fix", f"delay={DELAY!r}", "--quiet"]) == 0
    assert "delay 0.02 s" in capsys.readouterr().out


def test_a_held_gain_the_data_do_not_support_is_a_poor_fit_that_says_so():
    # the verdict was the free fit's: "ok ... exact to rounding" above a model whose max
    # rel. error was 0.333 (a command line's --fix dc_gain=1.5 for a gain of 2)
    w = np.logspace(-1, np.log10(200.0), 100)
    g = 2.0 / (1 + 0.1j * w + (1j * w / 10) ** 2) * np.exp(-0.02j * w)
    free = fc.fit(w, g, n_sections=1)
    assert free.status.value == "ok"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        held = fc.fit(w, g, n_sections=1, fixed={"dc_gain": 1.5})
    assert held.status.value == "poor-fit" and held.success     # (converged)
    assert held.model.frequency_response(np.array([1e-9]))[0].real == pytest.approx(1.5)
    assert held.max_rel_error > 0.2 and held.stages[-1].kind.value == "final"
    assert held.max_rel_error == pytest.approx(float(np.max(np.abs(
        g / held.model.frequency_response(w) - 1))), rel=1e-12)
    assert re.search(r"^poor-fit: converged, but the residual \(RMS 0\.\d+\) is [\d.]+ times "
                     r"the noise .* the likely cause is the held dc_gain 1\.5: without it "
                     r"the fit reaches RMS [\d.e-]+ \(max rel\. error [\d.e-]+\); check the "
                     r"value, or fit without it; dc_gain held at 1\.5", held.message)
    assert [d.values.get("cause") for d in held.diagnostics if d.code == "poor-fit"] == \
        ["held-gain"]
    # the right gain held: ok, as the free fit
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        right = fc.fit(w, g, n_sections=1, fixed={"dc_gain": 2.0})
    assert right.status.value == "ok" and right.max_rel_error < 1e-8


def test_a_held_gain_says_it_is_k0_when_the_auto_integrator_chose_a_pole_at_the_origin():
    w = np.logspace(-1, 2, 200)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = fc.fit(w, 4.0 / (1j * w * (1 + 1j * w / 2)), n_sections=1,
                     fixed={"dc_gain": 4.0})
    assert res.model.structure.origin_order == 1 and res.status.value == "ok"
    assert ("dc_gain held at 4 as K0 of K0/s (the model has 1 pole(s) at the origin; "
            "integrator=False holds G(0))") in res.message

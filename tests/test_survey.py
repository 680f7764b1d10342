"""Tests of the stabilization survey's estimators (freqid_casadi.modal.survey, _estimate)."""

import csv
import io

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.errors import OptionError
from freqid_casadi.modal import survey
from freqid_casadi.modal.survey import OrderEstimate

#: (omega_n rad/s, zeta) of the four modes of the noisy test structure.
MODES = ((12.0, 0.02), (31.0, 0.015), (55.0, 0.01), (90.0, 0.02))


def _noisy(seed=3, n_channels=3, n=300, noise=2e-3):
    """Three channels of a four-mode structure, 300 points 5..150 rad/s, 0.2 % complex
    noise (relative)."""
    rng = np.random.default_rng(seed)
    w = np.geomspace(5.0, 150.0, n)
    s = 1j * w
    shapes = rng.standard_normal((n_channels, len(MODES)))
    out = []
    for c in range(n_channels):
        g = sum(a / (s * s + 2 * z * p * s + p * p) for a, (p, z) in zip(shapes[c], MODES))
        g = g * (1 + noise * (rng.normal(size=n) + 1j * rng.normal(size=n)) / np.sqrt(2))
        out.append(fc.FrequencyData(w, g, f"ch{c + 1}"))
    return out


@pytest.mark.filterwarnings("ignore:fit_shared. the mode at")  # the full survey's spurious
def test_rational_survey_selects_the_modes_of_the_full_survey():
    datas = _noisy()
    fast = survey.stabilization(datas, "2:16:2", delay=False, zeros="free")
    full = survey.stabilization(datas, "2:16:2", delay=False, zeros="free",
                                estimator="full")
    assert fast.estimator == "rational" and full.estimator == "full"
    assert all(isinstance(f, OrderEstimate) for f in fast.fits)
    assert full.polished is None and fast.polished.success
    assert len(fast.modes) == len(full.modes) == len(MODES)
    # measured over the noise seeds 3..6: frequencies within 8.2e-6, damping ratios within
    # 1.5e-3 (relative) of the full survey's; allowed 10x
    np.testing.assert_allclose([m.omega_n for m in fast.modes],
                               [m.omega_n for m in full.modes], rtol=1e-4)
    np.testing.assert_allclose([m.zeta for m in fast.modes], [m.zeta for m in full.modes],
                               rtol=1.5e-2)
    # and near the structure's (0.2 % noise): measured 1.8e-5 and 1.3e-3; allowed 10x
    np.testing.assert_allclose([m.omega_n for m in fast.modes], [w for w, _ in MODES],
                               rtol=2e-4)
    np.testing.assert_allclose([m.zeta for m in fast.modes], [z for _, z in MODES],
                               rtol=1.3e-2)
    # the polished modes are those of the fit the result holds
    assert set(m.omega_n for m in fast.modes) <= set(m.omega_n for m in fast.polished.modes)
    # each selected pole of the diagram lies within freq_tol of its polished mode
    assert len(fast.selected_poles) == len(fast.modes)
    for p, m in zip(fast.selected_poles, fast.modes):
        assert p.order == 16 and abs(p.omega_n - m.omega_n) <= 0.01 * m.omega_n
    rows = list(csv.reader(io.StringIO(survey.stabilization_csv(fast))))
    assert sum(int(r[5]) for r in rows[1:]) == len(MODES)


def test_estimates_do_not_depend_on_the_number_of_jobs():
    datas = _noisy(n_channels=2, n=200)
    one = survey.stabilization(datas, "2:10:2", delay=False, zeros="free", polish=False)
    two = survey.stabilization(datas, "2:10:2", delay=False, zeros="free", polish=False,
                               n_jobs=2)
    assert [(p.order, p.omega_n, p.zeta, p.status) for p in one.poles] == \
        [(p.order, p.omega_n, p.zeta, p.status) for p in two.poles]
    for a, b in zip(one.fits, two.fits):
        np.testing.assert_array_equal(a.poles, b.poles)
        np.testing.assert_array_equal(a.max_rel_errors, b.max_rel_errors)


def test_without_polish_the_modes_are_the_top_estimate_s():
    res = survey.stabilization(_noisy(), "2:16:2", delay=False, zeros="free", polish=False)
    assert res.polished is None
    top = res.fits[-1]
    assert top.order == 16 and top.poles.shape == (16,) and top.status == "estimate"
    assert all(any(m is k for k in top.modes) for m in res.modes)
    assert [p.omega_n for p in res.selected_poles] == [m.omega_n for m in res.modes]
    assert len(res.modes) == len(MODES)
    # the estimate of the highest order explains each channel to its noise: measured max
    # rel. error 0.0068..0.0078 (0.2 % complex noise); allowed 0.02
    assert np.all(top.max_rel_errors < 0.02) and top.max_rel_errors.shape == (3,)


def test_estimate_residues_are_those_of_the_model_with_its_integrator():
    # G_c = a_c / (s (s^2 + 2 z p s + p^2)): the estimator fits s G_c, and the residue of
    # G_c at the pole q is a_c / (q (q - conj q))
    w = np.geomspace(1.0, 100.0, 200)
    s = 1j * w
    p, z = 20.0, 0.03
    amps = (1.0, -2.5)
    datas = [fc.FrequencyData(w, a / (s * (s * s + 2 * z * p * s + p * p)), f"ch{k}")
             for k, a in enumerate(amps)]
    res = survey.stabilization(datas, (2, 4), delay=False, zeros="free", integrator=True,
                               min_stable=1, polish=False)
    (mode,) = res.fits[0].modes
    q = p * (-z + 1j * np.sqrt(1 - z * z))
    assert mode.omega_n == pytest.approx(p, rel=1e-9) and mode.zeta == pytest.approx(z)
    # measured: within 1e-12 relative (exact data)
    np.testing.assert_allclose(mode.residues, [a / (q * (q - np.conj(q))) for a in amps],
                               rtol=1e-8)


@pytest.mark.parametrize("kw, needle", [
    (dict(estimator="fast"), "unknown estimator 'fast'; choose one of rational, full"),
    (dict(n_jobs=0), "n_jobs must be a positive integer"),
    (dict(n_jobs=True), "n_jobs must be a positive integer"),
    (dict(polish="yes"), "polish must be True or False"),
    (dict(n_section=4), "unknown fit option.*'n_section'.*fit_shared, which takes"),
    (dict(zeros="maximum-phase"), "unknown zeros 'maximum-phase'"),
    (dict(integrator=2), "integrator=True or False only"),
])
def test_options_are_checked_before_any_order_is_estimated(monkeypatch, kw, needle):
    calls = []
    monkeypatch.setattr(survey, "estimate_order", lambda *a: calls.append(a))
    with pytest.raises(OptionError, match=needle):
        survey.stabilization(_noisy(n=60), "2:6:2", **kw)
    assert calls == []

"""Tests of metrics.relative_error, stages.polish, the enums of StageRecord and the typed
failure of the rational start."""

import json

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.errors import DataError, SolverError
from freqid_casadi.core.metrics import ErrorStats, error_stats, relative_error
from freqid_casadi.fitting.stages import Kept, StageKind, polish


def _model():
    beta = [0.01, 2.0, 1.0, 0.05, 3.0, 1.0, 0.02, 4.0]
    return fc.RationalDelayModel(fc.Structure(1, False, True), beta)


def test_relative_error_stats_and_forms():
    model = _model()
    w = np.logspace(0, 1, 50)
    resp = model.frequency_response(w) * (1 + 0.01 * np.sin(w))
    stats = relative_error(model, w, resp)
    assert isinstance(stats, ErrorStats)
    expect = np.abs(0.01 * np.sin(w))
    np.testing.assert_allclose(stats.values, expect, rtol=1e-9, atol=1e-15)
    assert stats.max == np.max(stats.values) and stats.argmax == int(np.argmax(expect))
    assert stats.omega_at_max == w[stats.argmax]
    assert stats.rms == pytest.approx(np.sqrt(np.mean(expect ** 2)), rel=1e-9)
    data = fc.FrequencyData(w, resp)
    np.testing.assert_array_equal(relative_error(model, data).values, stats.values)
    np.testing.assert_array_equal(model.relative_error(data), stats.values)


@pytest.mark.parametrize("args, match", [
    ((np.ones(3),), "response is missing"),
    ((np.ones(3), np.ones(4)), "equal shapes"),
])
def test_relative_error_bad_input(args, match):
    with pytest.raises(DataError, match=match):
        relative_error(_model(), *args)
    with pytest.raises(DataError, match="at least one"):
        error_stats([])


def test_polish_refits_from_a_perturbed_model():
    model = _model()
    w = np.logspace(-0.5, 1.5, 120)
    data = fc.FrequencyData(w, model.frequency_response(w))
    start = fc.RationalDelayModel(model.structure, np.array(model.beta) * 1.05)
    pol = polish(start, data)
    assert pol.kept == Kept.SOLUTION and pol.result.success
    assert np.max(pol.model.relative_error(data)) < 1e-8
    assert np.max(start.relative_error(data)) > 1e-3
    lb, ub = pol.param.bounds()
    assert np.all(pol.start >= lb) and np.all(pol.start <= ub)
    with pytest.raises(DataError, match="polish"):
        polish(start, (w, data.response))


def test_stage_enums_compare_and_serialise_as_words():
    assert Kept.SOLUTION == "solution" and f"{Kept.IDENTITY_RETRY}" == "identity-retry"
    assert str(StageKind.FINAL) == "final"
    data = fc.systems.G_A().window(100)
    # init="peak": its section stage ends at its limit, so a final stage runs (with the
    # default init="relocate" the section stage converges on all data and none is needed)
    res = fc.fit(data, n_sections=1, integrator=True, start="sequential",
                 loop=fc.LoopOptions(init="peak", delay_search=False))
    kinds = [s.kind for s in res.stages]
    # (the kept model may be the h = 0 candidate, whose record then comes last: so on a
    # machine where numpy takes its AVX2 functions)
    assert kinds[0] == StageKind.GAIN_DELAY and StageKind.FINAL in kinds
    d = next(s for s in res.stages if s.kind == StageKind.FINAL).as_dict()
    assert json.loads(json.dumps(d))["kept"] in {k.value for k in Kept}
    assert json.loads(json.dumps(d))["kind"] == "final"


def test_failed_rational_start_is_a_solver_error(monkeypatch):
    from freqid_casadi.fitting import start as start_module
    from freqid_casadi.fitting.start import RationalStartError

    def boom(*args, **kwargs):
        raise np.linalg.LinAlgError("no fit")

    monkeypatch.setattr(start_module, "_start_at", boom)
    data = fc.systems.G_A().window(100)
    with pytest.raises(RationalStartError, match="rational start failed") as info:
        fc.fit(data, n_sections=1, integrator=True, start="rational")
    assert isinstance(info.value, SolverError)
    best = fc.fit(data, n_sections=1, integrator=True, start="best")
    assert best.start == "sequential" and set(best.start_max_rel_errors) == {"sequential"}


def test_fit_many_rejects_old_keywords_before_any_fit():
    from freqid_casadi.fitting.batch import fit_many

    with pytest.raises(TypeError, match=r"fit_many\(\) no longer takes gauge=; pass "
                                         r"loop=LoopOptions\(gauge='b1'\)"):
        fit_many([fc.systems.G_A()], n_sections=1, gauge="b1")
    with pytest.raises(fc.OptionError, match="unknown method"):
        fit_many([fc.systems.G_A()], n_sections=1, method="newton")

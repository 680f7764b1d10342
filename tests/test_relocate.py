"""The sequential loop's init="relocate" (issue 14: the main loop must converge).

Measured at the thesis's orders (2-core VM): A sequential 1433 IPOPT iterations, 11 of 19
stages at their limit, max rel. error 6.34e-6, success False with init="peak"; 126
iterations, no stage at its limit, 3.3e-14, success True with init="relocate" (the
default).
"""

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.examples import EXAMPLES
from freqid_casadi.objective import Parametrization
from freqid_casadi.relocate import relocated_start
from freqid_casadi.solvers.common import Status
from freqid_casadi.stages import stage_cost

pytestmark = pytest.mark.filterwarnings("ignore::freqid_casadi.errors.ResolutionWarning")


def _fit(name, loop=None, **kw):
    ex = EXAMPLES[name]
    return fc.fit(ex.system(), n_sections=ex.n_sections, integrator=ex.integrator,
                  loop=loop or fc.LoopOptions(), **kw)


def _at_limit(res):
    return [s.stage for s in res.stages if s.status == Status.MAX_ITER]


@pytest.fixture(scope="module")
def fit_c():
    return _fit("C")


def test_relocate_is_an_init_choice():
    from freqid_casadi.options import INITS

    assert INITS == ("peak", "identity", "relocate")
    with pytest.raises(fc.errors.OptionError, match="init"):
        fc.LoopOptions(init="relocated")


def test_default_init_is_relocate():
    assert fc.LoopOptions().init == "relocate"


def test_example_a_sequential_converges_within_600_iterations():
    res = _fit("A")
    assert res.success, res.message
    assert res.nit <= 600                       # measured 126 (init="peak": 1433)
    assert res.max_rel_error <= 1e-5            # measured 3.3e-14 (peak: 6.34e-6)
    assert _at_limit(res) == []                 # peak: 11 of 19 stages
    assert res.delay == pytest.approx(0.01, rel=1e-3)   # measured 0.01000131


def test_example_a_peak_init_is_still_available_and_worse():
    res = _fit("A", loop=fc.LoopOptions(init="peak"))
    assert res.nit > 1000                       # measured 1433
    assert res.max_rel_error > 1e-6             # measured 6.34e-6
    assert len(_at_limit(res)) >= 10            # measured 11


@pytest.mark.parametrize("start", ["sequential", "rational"])
def test_example_b_is_not_worse(start):
    res = _fit("B", start=start)
    assert res.success
    assert res.max_rel_error <= 0.3315          # 0.3314 before and after


def test_example_c_sequential_is_more_accurate_and_section_stages_end(fit_c):
    assert fit_c.max_rel_error <= 2e-6          # measured 9.36e-7 (peak: 4.94e-5)
    assert fit_c.nit <= 1200                    # measured 935 (peak: 2754)
    sections = [s for s in fit_c.stages if s.kind == "section"]
    assert len(sections) == 27
    assert all(s.status != Status.MAX_ITER for s in sections)   # peak: 10 of them


@pytest.mark.xfail(strict=True, reason="measured: C sequential's final all-data stage ends "
                   "at its limit (205 its from max rel. error 1.04e-6 to 9.36e-7), success "
                   "False; the same slow final stage as C's rational start")
def test_example_c_sequential_final_stage_converges(fit_c):
    assert _at_limit(fit_c) == []
    assert fit_c.success


@pytest.mark.xfail(strict=True, reason="measured: C rational: 213 IPOPT its, final stage at "
                   "its limit (200), max rel. error 1.37e-6, success False (the rational "
                   "path does not use the sequential init)")
def test_example_c_rational_converges():
    res = _fit("C", start="rational")
    assert res.success and _at_limit(res) == []


def _two_section_stage():
    beta = [0.0, 2.0, 1, 0.05, 3.0, 1, 0.02, 30.0, 1, 0.1, 20.0, 1, 0.03, 12.0]
    w = np.logspace(-1, 2, 80)
    true = fc.RationalDelayModel(fc.Structure(2, False, False), beta)
    data = fc.FrequencyData(w, true.frequency_response(w))
    param = Parametrization(fc.Structure(2, False, False), "dc", (3.0, 12.0), 2.0, 1.0)
    return data, param


def test_relocated_start_recovers_an_exact_two_section_model():
    data, param = _two_section_stage()
    # a poor start: both sections as cancelling pairs at their reference frequencies
    z0 = np.concatenate([[0.0, 1.0], param.new_section(3.0, 0.3, 3.0, 0.3, 3.0),
                         param.new_section(12.0, 0.3, 12.0, 0.3, 12.0)])
    z = relocated_start(param, data, z0)
    assert z is not None
    assert stage_cost(param, data, z0) > 1.0
    assert stage_cost(param, data, z) < 1e-12
    lb, ub = param.bounds()
    assert np.all(z >= lb) and np.all(z <= ub)


def test_relocated_start_is_none_when_not_better():
    data, param = _two_section_stage()
    z0 = np.concatenate([[0.0, 1.0], param.new_section(3.0, 0.3, 3.0, 0.3, 3.0),
                         param.new_section(12.0, 0.3, 12.0, 0.3, 12.0)])
    best = relocated_start(param, data, z0)
    assert relocated_start(param, data, best) is None
    # too few points for the poles: no fit
    assert relocated_start(param, data.window(9), z0) is None

"""With weights, start="best" and the h = 0 candidate are ranked by the weighted error."""

import numpy as np

import freqid_casadi as fc
from freqid_casadi.fitting.candidates import Candidate, choose
from freqid_casadi.studies.measured import actuator_frf


def test_choose_ranks_by_the_weighted_errors_when_given():
    # unweighted, the unconverged h = 0 fit looks 33 % better; weighted it is worse
    conv = Candidate("rational", (None, None, None, []), 0.0506, 0.012, True, 0.030, 0.010)
    h0 = Candidate("rational at h=0", (None, None, None, []), 0.0337, 0.011, False,
                   0.045, 0.014)
    assert choose([conv, h0]) is conv
    # without weighted numbers (NaN) the unweighted ones are used
    a = Candidate("a", (None, None, None, []), 0.0506, 0.012, True)
    b = Candidate("b", (None, None, None, []), 0.0337, 0.011, False)
    assert choose([a, b]) is b


def test_weighted_actuator_fit_keeps_the_converged_optimum():
    # the actuator's H1 with its inverse-variance weights: the unweighted ranking kept the
    # h = 0 candidate, 203 iterations at IPOPT's limit (max cos 0.48), delay 0, success False
    data = actuator_frf(min_coherence=0.99).data
    assert data.weights is not None
    res = fc.fit(data, n_sections=2, delay=True, start="best")
    assert res.success, res.message
    assert 5e-3 < res.model.delay < 1e-2
    rel = fc.core.metrics.relative_error(res.model, data).values
    w = data.weights / np.mean(data.weights)
    weighted_max = float(np.max(rel * np.sqrt(w)))
    h0 = fc.fit(data, n_sections=2, delay=False, start="best")
    rel0 = fc.core.metrics.relative_error(h0.model, data).values
    assert weighted_max <= float(np.max(rel0 * np.sqrt(w))) * 1.10


def test_termination_message_never_prints_a_nan_projection():
    # the weighted actuator fit's message said "||P r||/||r|| nan" (not computed: the
    # cosine test had failed first), or a stale value from an earlier point
    from freqid_casadi.solvers.termination import StageMonitor, Termination

    mon = StageMonitor(None, Termination())
    mon.cos, mon.allowed = 0.48, 1e-6
    assert "nan" not in mon.test_text() and "not computed" in mon.test_text()
    mon.proj = 3e-3
    assert "||P r||/||r|| 0.003" in mon.test_text()

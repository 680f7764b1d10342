"""One API grammar for fit_shared, prune_sections, the weight fit, modes and batches: solver
knobs in option objects (the old keywords keep working with a FutureWarning naming the new
spelling, and give the same models), progress through the one channel, validators in one
message shape, a status and one sentence with the next step."""

import json
import re
import warnings

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.core.model import RationalDelayModel, Structure
from freqid_casadi.core.modes import Modes
from freqid_casadi.errors import OptionError
from freqid_casadi.fitting.validation import prune_sections
from freqid_casadi.modal.shared import DEFAULT_METHOD, SharedStage
from freqid_casadi.uncertainty.weight import WeightResult, fit_uncertainty_weight

#: IPOPT's own status words, which no message of a success may show.
IPOPT_WORDS = ("Solve_Succeeded", "User_Requested_Stop", "Maximum_Iterations_Exceeded",
               "cos(r", "Solved_To_Acceptable_Level")


def _two_modes(n=200):
    """Two channels of the two modes 5 and 17 rad/s, exact data, no delay."""
    w = np.linspace(1.0, 30.0, n)
    s = 1j * w

    def g(r):
        return r[0] / (s * s + 0.2 * s + 25.0) + r[1] / (s * s + 1.02 * s + 289.0)

    return [fc.FrequencyData(w, g((1.0, 2.0)), "a"), fc.FrequencyData(w, g((1.5, 0.5)), "b")]


def _jsons(res):
    return [json.dumps(m.to_dict(), sort_keys=True) for m in res.models]


@pytest.fixture(scope="module")
def shared():
    return fc.fit_shared(_two_modes(), 2, delay=False, start="rational")


# ------------------------------------------------------------------ fit_shared's options
def test_old_keywords_warn_with_the_new_spelling_and_give_the_same_models():
    datas = _two_modes()
    with pytest.warns(FutureWarning) as said:
        old = fc.fit_shared(datas, 2, delay=False, start="rational", max_iter=30, n_vf_iter=4)
    text = " ".join(str(w.message) for w in said)
    assert "method=IpoptOptions(max_iter=30, final_max_iter=60)" in text
    assert "vector_fitting=VectorFittingOptions(n_iter=4)" in text
    assert all(w.filename == __file__ for w in said)            # points at the caller
    with warnings.catch_warnings():
        warnings.simplefilter("error", FutureWarning)
        new = fc.fit_shared(datas, 2, delay=False, start="rational",
                            method=fc.IpoptOptions(max_iter=30, final_max_iter=60),
                            vector_fitting=fc.VectorFittingOptions(n_iter=4))
    assert _jsons(old) == _jsons(new)
    assert new.options["final_max_iter"] == 60 and new.options["n_vf_iter"] == 4


def test_default_method_is_the_old_default(shared):
    assert (DEFAULT_METHOD.max_iter, DEFAULT_METHOD.final_max_iter) == (200, 400)
    assert shared.options["max_iter"] == 200 and shared.options["final_max_iter"] == 400
    assert shared.details["final_stage"]["max_iter"] == 400
    again = fc.fit_shared(_two_modes(), 2, delay=False, start="rational", method="ipopt")
    assert _jsons(again) == _jsons(shared)


@pytest.mark.parametrize("kwargs, match", [
    ({"method": fc.BarrierLMOptions()}, "method must be an IpoptOptions"),
    ({"method": "barrier-lm"}, "method must be an IpoptOptions"),
    ({"method": fc.IpoptOptions(hessian="gauss-newton")},
     r"uses only max_iter, final_max_iter of IpoptOptions, got hessian='gauss-newton'"),
    ({"method": fc.IpoptOptions(), "max_iter": 10}, "drop max_iter"),
    ({"vector_fitting": fc.VectorFittingOptions(), "n_vf_iter": 3}, "drop n_vf_iter"),
    ({"vector_fitting": 10}, "vector_fitting must be a VectorFittingOptions"),
    ({"max_iter": 0}, r"max_iter must be an integer >= 1, got 0; pass method=IpoptOptions"),
    ({"start": "fastest"}, r"^unknown start 'fastest'; choose one of best, rational, "
                           r"sequential$"),
    ({"zeros": "maybe"}, r"^unknown zeros 'maybe'; choose one of minimum-phase, free$"),
    ({"delay": "both"}, r"^unknown delay 'both'; choose one of per-channel, shared, False$"),
    ({"integrator": "no"}, r"^integrator must be True or False, got 'no'"),
    ({"balance_channels": 2}, r"^balance_channels must be True or False, got 2"),
    ({"progress": "bar"}, r"^progress must be True, False, 'lines' or a callable"),
    ({"channel_sections": -1}, r"^channel_sections must be an integer >= 0, got -1; pass"),
])
def test_bad_options_name_the_argument_and_the_fix(kwargs, match):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        with pytest.raises(OptionError, match=match):
            fc.fit_shared(_two_modes(20), 2, **kwargs)


def test_vector_fitting_options_check_their_field():
    with pytest.raises(OptionError, match=r"VectorFittingOptions.n_iter must be an integer "
                                          r">= 0, got -1"):
        fc.VectorFittingOptions(n_iter=-1)
    assert fc.VectorFittingOptions(n_iter=np.int64(3)).n_iter == 3


# ------------------------------------------------------------------ progress
def test_progress_callable_receives_every_stage_and_lines_write_them(capsys):
    seen = []
    res = fc.fit_shared(_two_modes(), 2, delay=False, start="sequential",
                        progress=seen.append)
    assert len(seen) == len(res.stages) == 4
    assert all(isinstance(r, SharedStage) for r in seen)
    assert [r.stage for r in seen] == [s.stage for s in res.stages]
    capsys.readouterr()
    fc.fit_shared(_two_modes(), 2, delay=False, start="rational", progress="lines")
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 2 and lines[0].startswith("stage  0:")
    fc.fit_shared(_two_modes(), 2, delay=False, start="rational", progress=True)
    assert capsys.readouterr().err == ""                # not a terminal: silent


# ------------------------------------------------------------------ status and message
def test_a_success_says_ok_without_the_optimiser_words(shared):
    assert shared.status == "ok" and shared.success
    assert re.match(r"ok: converged; worst channel max rel\. error \S+, RMS \S+, consistent "
                    r"with the noise in every channel", shared.message)
    assert not any(w in shared.message for w in IPOPT_WORDS)
    final = shared.details["final_stage"]
    assert final["solver_status"] == shared.stages[-1].solver_status
    assert final["iterations"] == shared.stages[-1].nit <= final["max_iter"]


def test_an_iteration_limit_names_the_option_that_lifts_it():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", fc.DataWarning)     # its modes are too narrow
        res = fc.fit_shared(_two_modes(), 2, delay=False, start="sequential",
                            method=fc.IpoptOptions(max_iter=3, final_max_iter=5))
    assert res.status == "not-converged" and not res.success
    assert res.message.startswith("not-converged: the final stage reached its iteration "
                                  "limit (5); worst channel max rel. error")
    assert ("— pass method=IpoptOptions(final_max_iter=50) to let it run further"
            in res.message)
    assert not any(w in res.message for w in IPOPT_WORDS)
    assert res.details["final_stage"]["status"] == "MAX_ITER"


# ------------------------------------------------------------------ modes
def test_modes_is_a_field_and_a_call_on_both_results(shared):
    assert isinstance(shared.modes, Modes) and shared.modes() is shared.modes
    assert [m.omega_n for m in shared.modes()] == pytest.approx([5.0, 17.0], rel=1e-6)
    assert shared.modes == tuple(shared.modes)
    single = fc.fit(_two_modes()[0], n_sections=2, delay=False)
    assert isinstance(single.modes, tuple) and single.modes() == single.modes
    assert len(single.modes) == 2
    assert single.modes[0].omega_n == pytest.approx(5.0, rel=1e-6)
    assert single.modes[0].omega_n_std is not None              # with the covariance's std


# ------------------------------------------------------------------ prune_sections
def _narrow_pair_case():
    """Two resolved modes plus a near-cancelling narrow pair between the samples (as
    test_validation), so prune_sections removes the pair and refits."""
    omega = np.logspace(-1, 2, 120)
    true = [0.0, 2.0, 1, 0.1, 2.0, 1, 0.05, 3.0, 1, 0.1, 20.0, 1, 0.05, 30.0]
    w = float(np.sqrt(omega[60] * omega[61]))
    bad = RationalDelayModel(Structure(3, integrator=False, delay=False),
                             np.concatenate([true, [1, 1e-3, w, 1, 1e-7, w]]))
    good = RationalDelayModel(Structure(2, integrator=False, delay=False), np.array(true))
    return bad, fc.FrequencyData(omega, good.frequency_response(omega))


def test_prune_max_iter_warns_and_equals_the_method_spelling():
    bad, data = _narrow_pair_case()
    with pytest.warns(FutureWarning, match=r"prune_sections\(max_iter=40\) is deprecated; "
                                           r"pass method=IpoptOptions\(final_max_iter=40\)"):
        old = prune_sections(bad, data, max_iter=40)
    new = prune_sections(bad, data, method=fc.IpoptOptions(final_max_iter=40))
    assert len(new.removed) == 1 and new.refit_success is not None
    assert old.model.to_json() == new.model.to_json()
    with pytest.raises(OptionError, match="method must be an IpoptOptions"):
        prune_sections(bad, data, method=fc.BarrierLMOptions())
    with pytest.raises(OptionError, match="drop max_iter"):
        prune_sections(bad, data, method=fc.IpoptOptions(), max_iter=40)


# ------------------------------------------------------------------ the weight fit
OMEGA = np.logspace(-1, 5, 300)
REL_ERROR = 1e-3 * np.abs((1 + 1j * OMEGA / 10) / (1 + 1j * OMEGA / 1000)) * \
    (1 + 0.3 * np.sin(3 * np.log(OMEGA)) ** 2)


def test_weight_old_keywords_warn_and_give_the_same_weight(capfd):
    with pytest.warns(FutureWarning, match=r"fit_uncertainty_weight\(max_iter=60\) is "
                                           r"deprecated; pass method=IpoptOptions"
                                           r"\(max_iter=60\)"):
        old = fit_uncertainty_weight(OMEGA, REL_ERROR, order=2, max_iter=60)
    new = fit_uncertainty_weight(OMEGA, REL_ERROR, order=2,
                                 method=fc.IpoptOptions(max_iter=60))
    assert old.gain == new.gain and old.sections == new.sections and old.nit == new.nit
    with pytest.warns(FutureWarning, match=r"verbose=False\) is deprecated"):
        quiet = fit_uncertainty_weight(OMEGA, REL_ERROR, order=1, verbose=False)
    assert quiet.order == 1
    with pytest.raises(OptionError, match="uses only max_iter, ipopt of IpoptOptions"):
        fit_uncertainty_weight(OMEGA, REL_ERROR, method=fc.IpoptOptions(final_max_iter=9))


def test_weight_progress_receives_every_order():
    seen = []
    res = fit_uncertainty_weight(OMEGA, REL_ERROR, order=2, progress=seen.append)
    assert [w.order for w in seen] == [0, 1, 2]
    assert all(isinstance(w, WeightResult) for w in seen) and seen[-1].gain == res.gain
    with pytest.raises(OptionError, match="progress must be"):
        fit_uncertainty_weight(OMEGA, REL_ERROR, progress="bar")


# ------------------------------------------------------------------ fit's unconverged message
@pytest.mark.parametrize("details, says, step", [
    ({"max_iter": 500, "method": "ipopt", "termination": {"rms_fall_per_iteration": 0.002}},
     "reached its iteration limit (500) while the error still fell 0.2 % per iteration",
     "pass method=IpoptOptions(final_max_iter=5000) to continue"),
    ({"max_iter": 500, "method": "ipopt", "termination": {"rms_fall_per_iteration": -0.05}},
     "reached its iteration limit (500) with the error no longer falling",
     "try start='best'"),
    ({"method": "barrier-lm", "solver_status": "inner_max_iter"},
     "reached the barrier-LM's limit of trial steps per inner solve (max_inner)",
     "pass method=BarrierLMOptions(max_inner=5000)"),
])
def test_an_unconverged_fit_says_what_stopped_it_and_what_to_pass(details, says, step):
    from types import SimpleNamespace

    from freqid_casadi.fitting._checks import _not_converged
    from freqid_casadi.solvers.common import Status

    last = SimpleNamespace(status=Status.MAX_ITER, details=details)
    text = _not_converged(last, SimpleNamespace(max=1e-3, rms=1e-4))
    assert text.startswith("not-converged: the final stage " + says), text
    assert step in text and "-5 %" not in text
    # at rounding level (example C: 1.1e-10) more iterations are not the way on
    text = _not_converged(last, SimpleNamespace(max=1e-9, rms=1e-10))
    assert text.startswith("not-converged: the final stage " + says), text
    assert text.endswith("— the model reproduces the data to rounding: more iterations "
                         "only move sections the data do not need (fewer sections shed "
                         "them)"), text


def test_an_unconverged_fit_with_narrow_roots_offers_the_damping_floor_first():
    # a transistor's S21 at 3 sections: "pass --final-max-iter 2000" took 554 s where
    # min_damping='auto' reached "ok" in 19 s; a floor already given is not offered again
    from freqid_casadi.core.resolution import ResolutionCheck
    from freqid_casadi.fitting._checks import not_usable_between_samples

    check = ResolutionCheck(ok=False, flags=(None,), narrow=(), n_sections=3, factor=1.0)
    message = ("not-converged: the final stage reached its iteration limit (200) while the "
               "error still fell 0.2 % per iteration; max rel. error 0.0021, RMS 0.00088 (the "
               "model is feasible and these errors are measured) — pass "
               "method=IpoptOptions(final_max_iter=2000) to continue")
    out = not_usable_between_samples(message, check, None)
    assert out.endswith("— 1 pole(s)/zero(s) are narrower than the frequency spacing: refit "
                        "with min_damping='auto' (a damping floor from the spacing), or pass "
                        "method=IpoptOptions(final_max_iter=2000) to continue"), out
    assert not_usable_between_samples(message, check, 'auto') == message
    assert not_usable_between_samples(message, ResolutionCheck(
        ok=True, flags=(), narrow=(), n_sections=3, factor=1.0), None) == message

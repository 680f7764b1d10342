"""The sequential loop's init="relocate": the main loop must converge.

With termination.hold_tol (the undamped zeros' dampings, 4e-17 off their bound, count as
on it), C's endpoints pass the gradient test and fail the projection test (the
Gauss-Newton step promises the whole residual); 2000 more IPOPT iterations from the
sequential fit's endpoint reach 8.0e-11 with max cos 0.00086 and ||P r||/||r|| 0.997.

Measured at the thesis's orders (2-core VM): A sequential 1433 IPOPT iterations, 11 of 19
stages at their limit, max rel. error 6.34e-6, success False with init="peak"; 126
iterations, no stage at its limit, 4.8e-14, success True with init="relocate" (the
default).

Example C does not converge with either start (measured on a 2-core VM with
``python scripts/final_stage_path.py [--start sequential]
[--delay H] --chunks N --chunk-iter K``). Both fits end in a basin whose delay is too small
(rational 0.026004 s, sequential 0.025947 s; G_C's delay is 0.02625 s), and their final
stage creeps towards the system's delay along an interior valley, not towards a boundary
of the model class: continued from the rational fit the cost keeps falling geometrically
(2.1e-11 after 300 more IPOPT iterations, 7.6e-12 after 3000, 2.4e-13 after 15000; max
rel. error 7.3e-7 -> 4.2e-7 -> 7.3e-8, still not stationary), the delay rises and levels
off below the system's (0.026004 -> 0.026049 s after 3000, 0.026105 s after 15000), no
root tends to 0 or infinity, no damping ratio reaches a bound except G_C's undamped zeros
(already within 1e-14 of it); the sections above the band (1.2e3..3.7e3 rad/s) and the
damped zeros in the band move most, and the exact Hessian (Jacobi scaled, held and
cancelling variables left out) keeps 4..8 negative eigenvalues there. Five sections of
either fit are exactly cancelling pole/zero pairs (the rational fit's below 0.13 rad/s, the
sequential fit's three there and two in the band); they never move, and holding them (or
the delay) fixed leaves the creep unchanged. The valley is not a solver artefact: IPOPT
regularises the Hessian at every
iteration (lg(rg) 4.4..5.7); from the polish's start a trust region with the exact Hessian
(scipy trust-exact, Jacobi scaled, 2000 its) reaches 5.0e-12, scipy's TRF (1000
evaluations) 1.1e-11, IPOPT 1.1e-11. A far better basin lies at the system's delay: the
vector fit at h = 0.02625 s is at 1.6e-8 and its polish reaches 3.3e-10 in 204 iterations
(cost 2.6e-19, 1e8 below the fits'), 1.4e-10 after 3000, still not stationary (the
undamped zeros' dampings, held 1e-16..1e-13 off their bound by the barrier, are 1e-4..2e-2
of ||r|| away at this cost and count as free; the other cosines, 0.012..0.015, are 1.5x
the test's rounding allowance). That basin is narrow: vector fits at 0.0261 / 0.0262 /
0.0263 / 0.0264 s polish (200 its) to 3.8e-7 / 1.6e-10 / 4.2e-7 / 1.9e-6; the rational
start's delay updates stall at 0.025995 s, where its vector fit (3.6e-6) beats the others
it tried (vector fitting's error is erratic in h: 1.6e-8 at 0.02625 s, 2.2e-4 at
0.02624 s).

Since LoopOptions(delay_search=True) (the default, freqid_casadi/delay_search.py), a fit
that did not converge also tries the vector fit at 17 delays around its own, polished: C
rational reaches 6.1e-11 at 0.0262293 s, C sequential 1.1e-10 at 0.0262470 s (the basin
above). Neither polish is stationary: at cost 1e-20 (max 6e-11, 200x the residual's rounding
level) the largest cosines are G_C's undamped zeros' dampings held 6e-17..2e-16 off their
bound (put onto it, two others turn inwards: 0.073) and the residual lies in the span of
the column-scaled Jacobian's singular directions at 1e-10..4e-9 of the largest, where the
linearised model promises 99.99 % and no step realises it (an LM step on the SVD, with the
held dampings on their bound, lowers the cost 18 % in 150 steps; MINPACK's LM, without the
bounds, reaches 3.9e-22 by moving three undamped zeros into the right half plane).
"""

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.systems.examples import EXAMPLES
from freqid_casadi.core.objective import Parametrization
from freqid_casadi.fitting.candidates import NEAR
from freqid_casadi.fitting.relocate import relocated_start
from freqid_casadi.solvers.common import Status
from freqid_casadi.fitting.stages import stage_cost

pytestmark = pytest.mark.filterwarnings("ignore::freqid_casadi.errors.ResolutionWarning")


def _fit(name, loop=None, **kw):
    ex = EXAMPLES[name]
    kw.setdefault("start", "sequential")        # the loop these tests measure
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
    assert res.nit <= 600                       # measured 133 (init="peak": 1433)
    assert res.max_rel_error <= 1e-5            # measured 4.8e-14 (peak: 6.34e-6)
    assert _at_limit(res) == []                 # peak: 11 of 19 stages
    # delay measured over the kernels and perturbations (results/reproducibility.md):
    # 0.0099947..0.0100179 s, 1.8e-3 off at worst; bound ~3x that
    assert res.delay == pytest.approx(0.01, rel=5e-3)


def test_example_a_peak_init_is_still_available_and_worse():
    # (without the delay search, which rescues this unconverged fit: tests/test_delay_search.py)
    res = _fit("A", loop=fc.LoopOptions(init="peak", delay_search=False))
    assert res.nit > 1000                       # measured 1433
    assert res.max_rel_error > 1e-6             # measured 6.34e-6
    assert len(_at_limit(res)) >= 10            # measured 11


@pytest.mark.parametrize("start", ["sequential", "rational"])
def test_example_b_is_not_worse(start):
    res = _fit("B", start=start)
    assert res.success
    assert res.max_rel_error <= 0.3315          # 0.3314 before and after


def test_example_c_sequential_is_more_accurate_with_fewer_stages_at_their_limit(fit_c):
    # C's result moves with rounding (issue 27, results/reproducibility.md): the delay
    # search's vector fits are erratic in the delay and its polish ends at its limit in a
    # narrow curved valley. Measured over the six OpenBLAS kernels and data perturbed by
    # 1e-15 (on an AVX-512 machine): max rel. error 4.9e-11..3.3e-7, 1600..1835 IPOPT
    # iterations, 3-4 stages at their limit. On an AVX2 machine (numpy's AVX2 functions)
    # the loop's first section settles at a delay of 0.10 s for 0.026 s and the loop ends
    # at 1.18 after 3014 iterations; the delay search's trial of the rational start
    # rescues it: 7.98e-7, 3237 iterations, 9 stages at their limit (7 sections, the
    # final stage, the polish); with numpy's baseline functions there, 7.42e-11, 1805, 3.
    # Bounds: the worst case times 2.5 and 1.15, and the worst + 1.
    assert fit_c.max_rel_error <= 2e-6
    assert fit_c.nit <= 3700
    assert len(_at_limit(fit_c)) <= 10
    assert len([s for s in fit_c.stages if s.kind == "section"]) == 27
    assert fit_c.stages[-1].kind == "delay-search"


@pytest.mark.xfail(strict=True, reason="measured: C sequential: 1771 IPOPT its, section "
                   "stage 20 (104 its), the loop's final stage (205 its, 9.15e-7, h 0.025947 "
                   "s) and the delay search's polish (204 its, max rel. error 1.09e-10, h "
                   "0.0262470 s) end at their limits, success False: not stationary, max "
                   "cos(r, J_j) 0.026 (allowed 0.032) but ||P r||/||r|| 1 (allowed 0.18), "
                   "the Gauss-Newton step promises a 99.7 % lower cost; module docstring")
def test_example_c_sequential_final_stage_converges(fit_c):
    assert _at_limit(fit_c) == []
    assert fit_c.success


@pytest.fixture(scope="module")
def fit_c_rational():
    return _fit("C", start="rational")


@pytest.mark.xfail(strict=True, reason="measured: C rational: 438 IPOPT its, the polish ends "
                   "at its limit (205 its, 8.33e-7, h 0.026004 s), the delay search's polish "
                   "too (204 its, max rel. error 6.08e-11, h 0.0262293 s), success False: not "
                   "stationary, max cos(r, J_j) 0.011 (allowed 0.055) but ||P r||/||r|| 1 "
                   "(allowed 0.23): the cost still falls; module docstring")
def test_example_c_rational_converges(fit_c_rational):
    res = fit_c_rational
    assert res.success and _at_limit(res) == []


def test_example_c_rational_and_its_delay_search_stay_within_the_measured_spread(fit_c_rational):
    res = fit_c_rational
    cands = res.candidate_max_rel_errors
    assert res.start == "rational"
    assert cands["rational"] > 1e-7                 # measured 7.7e-7..8.3e-7
    # The delay search usually rescues it: on the AVX-512 machine over six OpenBLAS kernels
    # 5.5e-11..4.1e-10 (delay 0.026165..0.026233 s); on the AVX2 machine over five kernels
    # and two numpy SIMD levels 4.0e-11..1.0e-7 (results/reproducibility.md; 1.0e-7 under
    # Nehalem, from 7.7e-7: the search's polish ended in another part of the valley, delay
    # 0.026371 s). With the data perturbed by 1e-15, one seed in ten on the AVX-512 machine
    # kept the unrescued fit (8.0e-7 at 0.026005 s): whether the search wins is decided at
    # the rounding level, so a bound that holds on every machine is the unrescued worst
    # (8.0e-7) times 2.5, and the delay within 1 % (0.9 % off at worst, 0.026005 s).
    assert res.max_rel_error <= NEAR * min(cands.values())
    assert res.max_rel_error <= 2e-6
    assert res.delay == pytest.approx(EXAMPLES["C"].true_delay, rel=1e-2)


def test_example_c_has_a_far_better_basin_at_the_systems_delay():
    """Why C's xfails above: the fits end at h ~ 0.0260 s; a vector fit at G_C's delay
    polished for 200 iterations is more accurate (module docstring).

    Vector fitting 27 sections is itself erratic under rounding (issue 27): at h =
    0.02625 s it reaches 1.6e-8 (SkylakeX), 2.6e-8 (Haswell) but 2.2e-4 with
    OPENBLAS_CORETYPE=Prescott, and its polish 3.3e-10 / 6.0e-10 / 1.9e-7 at h 0.0262499 /
    0.0262498 / 0.0262512 s. Bounds: the worst case times ~5 (error) and ~10 (delay)."""
    from freqid_casadi.core.resolution import default_delay_max
    from freqid_casadi.fitting.stages import polish
    from freqid_casadi.fitting.start import rational_start

    ex = EXAMPLES["C"]
    data = ex.system()
    rs = rational_start(data, fc.Structure(ex.n_sections, ex.integrator, ex.delay),
                        delay_max=default_delay_max(data.omega), delay0=ex.true_delay,
                        max_delay_updates=1)
    assert rs.max_rel_error < 1e-3
    pol = polish(rs.model, data, max_iter=200)
    assert np.max(pol.model.relative_error(data)) < 1e-6
    assert pol.model.delay == pytest.approx(ex.true_delay, rel=5e-4)


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
    found = relocated_start(param, data, z0)
    assert found is not None
    new, z = found
    assert stage_cost(param, data, z0) > 1.0
    assert stage_cost(new, data, z) < 1e-12
    lb, ub = new.bounds()
    assert np.all(z >= lb) and np.all(z <= ub)
    # the relocated sections' own references: the variables are about 1
    assert sorted(new.omega_ref) == pytest.approx([12.0, 30.0], rel=1e-6)
    assert np.all(z[2:] < 100)               # measured max 16 (a zero at 3 with a pole at 12)


def test_relocated_start_is_none_when_not_better():
    data, param = _two_section_stage()
    z0 = np.concatenate([[0.0, 1.0], param.new_section(3.0, 0.3, 3.0, 0.3, 3.0),
                         param.new_section(12.0, 0.3, 12.0, 0.3, 12.0)])
    new, best = relocated_start(param, data, z0)
    assert relocated_start(new, data, best) is None
    # too few points for the poles: no fit
    assert relocated_start(param, data.window(9), z0) is None

"""The validation corpus (issue 26): the generator, the automatic order and a seeded subset
of 60 cases fitted with today's defaults.

The subset: ``corpus(60, seed=0, max_points=50)`` (every case cut to 50 points so the 60
fits take a minute or two), fitted at the true order by
:func:`freqid_casadi.studies.corpus.run_corpus` with the defaults. Measured values are in
the comments; the thresholds keep a stated margin below them.
"""

import json
import math
import warnings

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.errors import OptionError
from freqid_casadi.fitting.order import choose_order, significant, whiteness
from freqid_casadi.studies.corpus import (EXACT_FLOOR, FLOOR_FACTOR, fit_case, run_corpus,
                                          summarize)
from freqid_casadi.systems import corpus as make_corpus
from freqid_casadi.systems.corpus import FAMILIES, case


# -- the generator ----------------------------------------------------------------------

def test_corpus_is_deterministic_and_a_prefix():
    a, b = make_corpus(12, seed=3), make_corpus(12, seed=3)
    for x, y in zip(a, b):
        assert np.array_equal(x.data.response, y.data.response)
        assert x.family == y.family and x.delay == y.delay
    c = case(7, seed=3)
    assert np.array_equal(c.data.response, a[7].data.response)
    assert not np.array_equal(make_corpus(12, seed=4)[7].data.response, c.data.response)
    assert [x.family for x in a[:9]] == list(FAMILIES)


def test_corpus_spans_the_families_ranges():
    cases = make_corpus(300)
    points = [c.n_points for c in cases]
    assert min(points) >= 50 and max(points) <= 5000 and max(points) > 2000
    lo = min(c.data.omega[0] for c in cases)
    hi = max(c.data.omega[-1] for c in cases)
    assert 1e-3 <= lo < 1e-2 and 1e8 < hi <= 1e9
    assert {c.spacing for c in cases} == {"log", "linear"}
    noise = [c.noise for c in cases]
    assert min(noise) == 0 and 0.04 < max(noise) <= 0.05
    assert any(c.variance_given for c in cases) and not all(c.variance_given for c in cases
                                                          if c.noise > 0)
    damp = [c.min_damping for c in cases]
    assert min(damp) < 0.003
    assert sum(c.delay == 0 for c in cases) > 100
    fams = {f: [c for c in cases if c.family == f] for f in FAMILIES}
    assert all(len(v) >= 33 for v in fams.values())
    assert all(c.gain_sign == -1 for c in fams["negative-gain"])
    assert all(c.integrators in (1, 2) and not c.in_class for c in fams["integrator"])
    assert all(c.zeros_at_origin == 2 for c in fams["accelerance"])
    assert all(c.zeros_at_origin == 1 for c in fams["band-pass"])
    nmp = [c for c in fams["modal-noncollocated"] if c.nmp_zeros]
    assert nmp and all(not c.in_class for c in nmp)
    assert all(c.in_class for f in ("in-class", "modal-collocated", "modal-feedthrough")
               for c in fams[f])


def test_case_data_is_the_truth_times_the_noise():
    for c in make_corpus(27):
        dev = np.abs(c.data.response / c.truth(c.data.omega) - 1)
        if c.noise == 0:
            assert dev.max() < 1e-12
        else:
            # complex Gaussian of RMS sigma_i: the mean of |n|^2 / sigma^2 is near 1
            assert 0.5 < np.mean((dev / c.sigma) ** 2) < 1.6
        if c.variance_given:
            assert np.allclose(c.data.weights, 1 / c.sigma ** 2)
        assert c.delay <= 0.85 * math.pi / np.max(np.diff(c.data.omega)) * (1 + 1e-12)


@pytest.mark.parametrize("index", [4, 5])       # linear spacing; log, variance given
def test_a_case_resampled_keeps_its_band_spacing_and_noise(index):
    c = case(index, 0)
    d = c.resampled(3000, np.random.default_rng(7))
    w = c.data.omega
    assert d.n_points == 3000
    assert d.omega[0] == w[0] and d.omega[-1] == pytest.approx(w[-1], rel=1e-12)
    steps = np.diff(d.omega) if c.spacing == "linear" else np.diff(np.log(d.omega))
    assert np.ptp(steps) < 1e-6 * steps.mean()
    sigma = np.interp(np.log(d.omega), np.log(w), c.sigma)
    dev = np.abs(d.response / c.truth(d.omega) - 1)
    # 3000 draws of |n|^2 / sigma^2 (mean 1, sd 1): their mean within 0.9-1.1
    assert 0.9 < np.mean((dev / sigma) ** 2) < 1.1
    assert (d.weights is not None) == c.variance_given
    if c.variance_given:
        assert np.allclose(d.weights, 1 / sigma ** 2)


def test_a_noncollocated_zero_is_where_the_truth_vanishes():
    c = next(x for x in make_corpus(60) if x.nmp_zeros)
    z = c.truth.finite_zeros()
    z = z[z.real > 0][0]
    assert abs(c.truth.at(np.array([z]))[0]) < 1e-6 * np.max(np.abs(c.truth(c.data.omega)))


@pytest.mark.parametrize("kw, match", [({"n": 0}, "n must"), ({"families": ["x"]}, "unknown"),
                                       ({"max_points": 10}, "max_points")])
def test_corpus_bad_arguments(kw, match):
    with pytest.raises(OptionError, match=match):
        make_corpus(**dict({"n": 3}, **kw))


# -- the automatic order ----------------------------------------------------------------

def test_whiteness_tells_noise_from_structure():
    rng = np.random.default_rng(1)
    noise = rng.standard_normal(400) + 1j * rng.standard_normal(400)
    assert whiteness(noise)[1] == pytest.approx(1, abs=0.15)
    smooth = np.exp(1j * np.linspace(0, 3, 400))
    assert whiteness(smooth)[1] > 20
    assert significant(1.0, 0.5, 100) and not significant(1.0, 0.95, 100)


def test_auto_order_on_a_noisy_in_class_case():
    c = case(0)                     # 3 sections, 56 points, 0.45 % noise
    res = fc.fit(c.data, n_sections="auto")
    rec = next(d for d in res.diagnostics if d.code == "order-chosen")
    # measured: 1: 0.83 (x2.8), 2: 0.52 (x2.2), 3: 0.0040 (x0.92), 4: 0.0039; chose 3
    assert res.model.n_sections == 3 and rec.values["reason"] == "consistent"
    assert rec.values["orders"] == [1, 2, 3, 4]
    assert res.rms_rel_error < FLOOR_FACTOR * c.noise
    assert "chose 3 sections" in rec.message


def test_a_replayed_ladder_chooses_what_the_live_search_chose():
    # the same case and orders as above, fitted once each, the rule replayed over them
    from freqid_casadi.studies.corpus_order import judge, ladder, replay

    lad = ladder((0, 0, 5000), top=4)
    assert [o["n_sections"] for o in lad["orders"]] == [1, 2, 3, 4]
    assert replay(lad) == (3, "consistent")
    assert replay(dict(lad, orders=lad["orders"][:3])) == (None, "beyond")
    [v] = judge([lad])
    assert v["right"] and not v["below"] and not v["above"] and v["subset"]


def test_a_mode_the_noise_share_misses_is_kept_by_the_f_test():
    from freqid_casadi.fitting.order import OrderStep, beats_noise, decide

    # negative-gain-40's ladder (55 points, 6 sections true): RMS (x roughness) of 1..7
    measured = [(0.727, 2.19), (0.588, 2.22), (0.26, 1.05), (0.154, 1.02), (0.00378, 1.12),
                (0.00307, 0.96), (0.00299, 0.97)]
    steps = [OrderStep(n, rms, ratio, True) for n, (rms, ratio) in enumerate(measured, 1)]
    poles = [np.array([-1 + 10j, -1 - 10j])] * 7
    omega = np.array([1.0, 100.0])
    # 5 -> 6 sections lower the consistent residual's RMS by 19 %: the 12 / M share asks
    # 22 % and stopped at 5; the F-test (F = 10.8 on 4 and 84 degrees of freedom, 1 %
    # quantile 3.5) keeps the sixth mode, and 6 -> 7 (2.6 %, below MIN_FALL) stops there
    assert decide(steps[:6], poles[:6], omega, 55, alpha=0.0) == (4, "consistent")
    assert decide(steps[:6], poles[:6], omega, 55) is None
    assert decide(steps, poles, omega, 55) == (5, "consistent")
    # on 10 000 points a 2 % fall passes the F-test (F = 206) but not the practical floor
    a, b = OrderStep(4, 0.0100, 1.0, True), OrderStep(5, 0.0098, 1.0, True)
    assert not beats_noise(a, b, 10000) and beats_noise(a, b, 10000, min_fall=0.0)
    # a 3.5 % fall on 120 points: F = 4.0 on (4, 218) against 3.4 at 1 %, 4.8 at 0.1 %
    c = OrderStep(5, 0.00721 * 0.965, 1.0, True)
    before = OrderStep(4, 0.00721, 1.0, True)
    assert beats_noise(before, c, 120) and not beats_noise(before, c, 120, alpha=0.001)


def test_an_order_is_consistent_only_where_the_status_check_agrees():
    from freqid_casadi.fitting.order import OrderStep, decide

    # a Bode 100 measurement of a filter (400 points; noise 10x larger above its
    # resonance than below): 3 sections leave a smooth residual below the resonance,
    # RMS 0.00259 at 1.12 times the roughness the noisy band dominates, 18.9 times the
    # local noise; 4 sections lower it by 2.7 %. Read by the roughness alone, 3 sections
    # were "consistent with the noise" while the fit's status said poor-fit
    measured = [(0.0446, 13.0, 80.0), (0.00946, 3.8, 60.0), (0.00259, 1.12, 18.9),
                (0.00252, 1.1, 18.0), (0.0025, 1.1, 17.5)]
    steps = [OrderStep(n, rms, ratio, True, local_ratio=local)
             for n, (rms, ratio, local) in enumerate(measured, 1)]
    poles = [np.array([-1 + 10j, -1 - 10j])] * 5
    omega = np.array([60.0, 3e5])
    assert decide(steps[:4], poles[:4], omega, 400) is None
    assert decide(steps, poles, omega, 400) == (2, "no-improvement")
    plain = [OrderStep(s.n_sections, s.rms, s.ratio, True) for s in steps]    # not measured
    assert decide(plain[:4], poles[:4], omega, 400) == (2, "consistent")
    agreed = [OrderStep(s.n_sections, s.rms, s.ratio, True, local_ratio=1.9) for s in steps]
    assert decide(agreed[:4], poles[:4], omega, 400) == (2, "consistent")


def test_an_order_step_counts_the_parameters_the_data_determine():
    # gain, delay, 2 poles and 2 zeros: 6, not Structure.n_params's 8 (the unit-DC gauge
    # fixes two); counted as 8, the F-test had kept accelerance-222 at 4 sections of 5
    from freqid_casadi.fitting.order import _step

    w = np.logspace(-1, 1, 60)
    s = 1j * w
    res = fc.fit(w, 4 / (s * s + 0.2 * s + 4) * np.exp(-0.1 * s), n_sections=1)
    assert res.model.structure.n_params == 8
    assert _step(res)[0].n_params == 6


def test_a_structured_residual_needs_only_the_floor_to_count_as_better():
    from freqid_casadi.fitting.order import OrderStep, decide, noise_share

    # negative-gain-148's ladder (63 points, 4 sections): RMS (x roughness) of 1..5 sections
    measured = [(0.69, 4.7), (0.614, 3.4), (0.577, 9.0), (0.013, 0.9), (0.0129, 0.92)]
    steps = [OrderStep(n, rms, ratio, True) for n, (rms, ratio) in enumerate(measured, 1)]
    poles = [np.array([-1 + 10j, -1 - 10j])] * 5           # the same modes at every order
    omega = np.array([1.0, 100.0])
    assert noise_share(steps[3]) == 1.0
    assert noise_share(steps[0]) == pytest.approx(1 / 4.7 ** 2)
    # the previous rule asked every order for a 19 % fall (12 / 63) and stopped at 1 section
    old = decide(steps[:3], poles[:3], omega, 63, share=lambda step: 1.0)
    assert old == (0, "no-improvement")
    # with the noise's share of each structured residual, 0.69 -> 0.614 (11 %) counts
    assert all(decide(steps[:k], poles[:k], omega, 63) is None for k in (2, 3, 4))
    assert decide(steps, poles, omega, 63) == (3, "consistent")


def test_the_order_record_says_when_the_next_order_raises_the_rms():
    from freqid_casadi.fitting.order import OrderStep, _choice

    # line.s2p of scikit-rf at 4 and 5 sections: the fifth ended far above the fourth
    steps = [OrderStep(4, 2.98e-11, 4.8, True), OrderStep(5, 6.6e-06, 11.0, True)]
    poles = [np.array([-1 + 10j, -1 - 10j])] * 2
    choice = _choice([None, None], steps, poles, 0, "consistent", np.array([1.0, 100.0]))
    assert "5 sections do not lower the RMS (RMS 6.6e-06) and move" in choice.message
    steps[1] = OrderStep(5, 2.5e-11, 1.0, True)
    choice = _choice([None, None], steps, poles, 0, "consistent", np.array([1.0, 100.0]))
    assert "5 sections lower the RMS by 16 % and move" in choice.message


def test_auto_order_stops_at_max_sections():
    c = case(3)                     # right-half-plane zeros: no order is consistent
    choice = choose_order(lambda n: fc.fit(c.data, n_sections=n), max_sections=2)
    assert choice.reason in ("max-sections", "no-improvement")
    assert [s.n_sections for s in choice.steps] == [1, 2]
    # the order rule's test is named: it is stricter than the status check ("ok" at twice
    # the local noise), so the record does not read as contradicting an "ok" status
    assert ("no residual passes the order rule's noise test (RMS at most 1.3 times its "
            "point-to-point roughness and 2 times the local noise)") in choice.message


def _rhp_pair_data():
    """Two modes and a right-half-plane zero pair at 8 rad/s inside the band (exact)."""
    w = np.geomspace(1, 100, 200)
    s = 1j * w
    g = 5 * (s * s - 0.8 * s + 64) / (s * s + 0.2 * s + 25) / (s * s + 1.2 * s + 400) * 6.25
    return fc.FrequencyData(w, g)


def test_a_minimum_phase_search_without_a_consistent_order_offers_the_free_zeros_one():
    import dataclasses

    from freqid_casadi.fitting.order import with_free_zeros

    data = _rhp_pair_data()
    opts = dict(integrator=False, delay=False)

    def minimum_phase(n):           # its own per-fit alternative removed: the search's
        res = fc.fit(data, n_sections=n, **opts)
        return dataclasses.replace(res, alternatives={})
    choice = choose_order(minimum_phase, max_sections=2)
    assert choice.reason != "consistent" and choice.result.rms_rel_error > 0.3
    res = with_free_zeros(choice, lambda n: fc.fit(data, n_sections=n, zeros="free", **opts),
                          max_sections=2)
    alt = res.alternatives["zeros=free"]
    # measured: the free-zeros search chooses 2 sections at RMS 2.6e-16
    assert alt.model.n_sections == 2 and alt.rms_rel_error < 1e-8 and alt.status == "ok"
    assert res.model.structure.zeros == "minimum-phase"
    assert res.message.endswith("zeros='free' reaches RMS "
                                f"{alt.rms_rel_error:.3g} at 2 sections — pass zeros='free' "
                                "(FitResult.alternatives['zeros=free'])")
    diag = [d for d in res.diagnostics if d.code == "non-minimum-phase"][-1]
    assert diag.severity == "warning" and diag.values["alternative_n_sections"] == 2
    # a search that found a consistent order is left alone (no second search)
    ok = choose_order(lambda n: fc.fit(data, n_sections=n, zeros="free", **opts),
                      max_sections=3)
    assert ok.reason == "consistent"
    assert "zeros=free" not in with_free_zeros(ok, None, max_sections=3).alternatives


def test_auto_order_stops_where_the_offered_free_zeros_model_explains_the_data():
    # the minimum-phase fits stay at RMS 0.35 from 2 sections on; the 2-section fit's
    # non-minimum-phase check offers the free-zeros model, exact: the search stops there
    # (before: "no-improvement" after 4 orders, the offered model not named by the order)
    res = fc.fit(_rhp_pair_data(), n_sections="auto", integrator=False, delay=False)
    rec = next(d for d in res.diagnostics if d.code == "order-chosen")
    assert rec.values["reason"] == "free-zeros" and rec.values["orders"] == [1, 2, 3]
    assert rec.values["free_zeros"] == [False, True, True]
    assert res.model.n_sections == 2 and res.model.structure.zeros == "minimum-phase"
    assert res.status == "poor-fit" and res.rms_rel_error > 0.3
    alt = res.alternatives["zeros=free"]
    assert alt.model.n_sections == 2 and alt.rms_rel_error < 1e-8
    assert "with free zeros RMS" in rec.message and "pass zeros='free'" in res.message


def test_explaining_step_takes_the_offered_model_only_where_it_explains_more():
    from freqid_casadi.fitting.order import OrderStep, decide, explaining_step

    mp, free = OrderStep(5, 0.18, 9.0, True), OrderStep(5, 0.00245, 0.95, True)
    assert explaining_step(mp) is mp and explaining_step(mp, free).free
    # a consistent minimum-phase fit is kept; an alternative not halving the RMS is not used
    ok = OrderStep(5, 0.0025, 1.0, True)
    assert explaining_step(ok, free) is ok
    assert explaining_step(mp, OrderStep(5, 0.1, 1.0, True)) is mp
    # modal-noncollocated-39's orders 4-6 (measured): 4 minimum phase only, 5 and 6 offered
    steps = [OrderStep(4, 0.217, 2.3, True), explaining_step(mp, free),
             explaining_step(OrderStep(6, 0.155, 7.6, True), OrderStep(6, 0.00245, 0.95, True))]
    poles = [np.array([-1 + 10j, -1 - 10j])] * 3
    assert decide(steps[:2], poles[:2], np.array([1.0, 100.0]), 100) is None
    assert decide(steps, poles, np.array([1.0, 100.0]), 100) == (1, "free-zeros")


def test_replay_reads_the_offered_free_zeros_model_as_the_live_search_does():
    from freqid_casadi.studies.corpus_order import judge, replay

    pole = [[-1.0, 10.0], [-1.0, -10.0]]

    def order(n, rms, ratio, free=None):
        o = dict(n_sections=n, rms=rms, ratio=ratio, success=True, status="poor-fit",
                 poles=pole)
        if free is not None:
            o["free"] = dict(rms=free[0], ratio=free[1], success=True, status="ok",
                             poles=pole)
        return o
    # modal-noncollocated-39's ladder (measured, 5 sections true): minimum phase never at
    # the noise; orders 5 and 6 offer a free-zeros model at it
    lad = dict(task=[39, 0, 120], case="modal-noncollocated-39", family="modal-noncollocated",
               true_sections=5, noise=0.00245, n_points=100, in_class=False,
               omega=[1.0, 100.0],
               orders=[order(1, 0.999, 58), order(2, 0.466, 2.7), order(3, 0.322, 2.3),
                       order(4, 0.217, 2.3), order(5, 0.179, 9, (0.00245, 0.95)),
                       order(6, 0.155, 7.6, (0.00245, 0.95)), order(7, 0.138, 5.9),
                       order(8, 0.137, 7.0)])
    assert replay(lad) == (5, "free-zeros")
    assert replay(lad, free_zeros=False) == (None, "beyond")     # needs orders above 8
    [v] = judge([lad])
    assert v["right"] and not v["floor"]


def test_auto_order_on_data_no_order_explains_stops_at_the_data_limit():
    # white noise: every order stays near the trivial model (RMS ~1), so the search runs
    # until the next order needs more parameters than 24 points give (fit raised that
    # DataError through n_sections="auto")
    rng = np.random.default_rng(0)
    w = np.geomspace(1, 100, 24)
    data = fc.FrequencyData(w, rng.standard_normal(24) + 1j * rng.standard_normal(24))
    res = fc.fit(data, n_sections="auto")
    rec = next(d for d in res.diagnostics if d.code == "order-chosen")
    assert rec.values["reason"] == "data-limit" and rec.values["orders"] == [1, 2, 3]
    assert res.status != "ok"


@pytest.mark.parametrize("n", ["many", range(0, 3), range(1, 5, 2), range(2, 2)])
def test_auto_order_bad_options(n):
    with pytest.raises(OptionError, match="positive integer, 'auto' or a range"):
        fc.fit(case(0).data, n_sections=n)


def test_auto_order_over_a_range():
    res = fc.fit(case(18).data, n_sections=range(2, 4))   # 1 true section, 1.6 % noise
    rec = next(d for d in res.diagnostics if d.code == "order-chosen")
    assert rec.values["orders"][0] == 2 and max(rec.values["orders"]) <= 3


def test_cli_sections_accepts_auto():
    from freqid_casadi.cli.app import build_parser

    args = build_parser().parse_args(["fit", "x.csv", "--sections", "auto", "--out", "r"])
    assert args.sections == "auto" and args.max_sections is None
    with pytest.raises(Exception, match="positive integer or 'auto'"):
        build_parser().parse_args(["fit", "x.csv", "--sections", "many", "--out", "r"])


# -- the seeded subset ------------------------------------------------------------------

@pytest.fixture(scope="module")
def subset():
    records = run_corpus(60, 0, max_points=50, workers=1, configs=["today"], auto=False)
    return records, summarize(records)["today"]


def test_subset_runs_every_case(subset):
    records, s = subset
    assert len(records) == 60 and s["all"]["errors"] == 0


def test_subset_in_class_at_the_floor(subset):
    # measured: 29 of the 48 in-class cases (0.604) at the floor (data); margin 0.1 (5
    # cases). The misses: accelerances and high-pass data (zeros at the origin, taken for
    # a negative gain) and local minima of the sequential start
    assert subset[1]["in-class cases"]["at_floor"] >= 0.604 - 0.1


def test_subset_sign(subset):
    # measured: 7 of the 7 negative-gain cases with the right sign, all at the floor;
    # margin: one case
    assert subset[1]["negative-gain"]["sign_right"] >= 1.0 - 0.15
    assert subset[1]["negative-gain"]["at_floor"] >= 1.0 - 0.15


def test_subset_never_ok_far_above_the_noise(subset):
    # with FitResult.status: no fit of the subset says "ok" with an RMS > 10x the noise
    # (before the status, 14 of 60 claimed success there)
    assert subset[1]["all"]["dishonest"] == 0


def test_subset_record_definitions(subset):
    for r in subset[0]:
        assert r.nu == max(r.noise, EXACT_FLOOR)
        assert r.at_floor == (r.rms <= FLOOR_FACTOR * r.nu)
        assert r.dishonest == (r.claims_ok and r.rms > 10 * r.nu)


def test_fit_case_records_a_time_limit(monkeypatch):
    import freqid_casadi.studies.corpus as study

    monkeypatch.setattr(study, "CPU_BUDGET", 0.0)
    rec = fit_case((1, 0, 50, "today"))
    assert rec.error.startswith("TimeLimit") and not rec.claims_ok


def test_run_corpus_resumes_from_its_checkpoint(tmp_path):
    path = tmp_path / "fits.jsonl"
    first = run_corpus(1, 0, max_points=50, workers=1, configs=["today"], auto=False,
                       checkpoint=path)
    seen = []
    again = run_corpus(1, 0, max_points=50, workers=1, configs=["today"], auto=False,
                       checkpoint=path, progress=lambda done, total, rec: seen.append(rec))
    assert seen == [] and len(path.read_text().splitlines()) == 1
    assert again[0].rms == first[0].rms and again[0].diagnostics == first[0].diagnostics
    # a record made by other code (another fingerprint) is set aside and fitted again
    rec = json.loads(path.read_text())
    path.write_text(json.dumps(dict(rec, code="0" * 16)) + "\n")
    seen.clear()
    run_corpus(1, 0, max_points=50, workers=1, configs=["today"], auto=False,
               checkpoint=path, progress=lambda done, total, rec: seen.append(rec))
    assert len(seen) == 1 and len(path.read_text().splitlines()) == 2


def test_json_lines_keeps_the_records_of_this_code(tmp_path, capsys):
    from freqid_casadi.report.folder import code_fingerprint
    from freqid_casadi.studies.corpus import json_lines

    path = tmp_path / "c.jsonl"
    mine, other = {"a": 1, "code": code_fingerprint()}, {"a": 2, "code": "x"}
    path.write_text(f"{json.dumps(mine)}\n{json.dumps(other)}\n{{\"cut\n")
    assert json_lines(path) == [mine, other]          # a cut line is skipped
    assert json_lines(path, code_fingerprint()) == [mine]
    assert "1 of its 2 records were made by other code" in capsys.readouterr().err
    assert json_lines(tmp_path / "none.jsonl", "x") == []


def test_the_order_record_of_weighted_data_says_its_rms_is_weighted():
    # a frf sidecar's weights: the status line's RMS (unweighted relative error, 0.18)
    # and the order record's (the weighted residual the rule reads, 0.0556) read as two
    # RMS of one model; the record now says which
    w = np.geomspace(1.0, 100.0, 60)
    s = 1j * w
    g = 2.0 / (s * s + 0.6 * s + 25.0) * 12.5
    weights = np.geomspace(1.0, 4.0, 60)
    res = fc.fit(fc.FrequencyData(w, g, weights=weights), n_sections=range(1, 3))
    (rec,) = [d for d in res.diagnostics if d.code == "order-chosen"]
    assert "orders tried (weighted RMS, x roughness" in rec.message
    assert "1: weighted RMS" in rec.message
    plain = fc.fit(fc.FrequencyData(w, g), n_sections=range(1, 3))
    (rec,) = [d for d in plain.diagnostics if d.code == "order-chosen"]
    assert "orders tried (RMS, x roughness" in rec.message and "weighted" not in rec.message


# -- resonance peaks: the order search's lower bound on many-mode data ---------------------

def _five_modes(w):
    s = 1j * w
    return sum(x ** 2 / (s ** 2 + 0.02 * x * s + x ** 2) for x in (2.0, 6.0, 20.0, 60.0, 200.0))


def test_resonance_peaks_are_counted_above_the_noise():
    from freqid_casadi.fitting.order import resonance_count

    w = np.logspace(0, 3, 1024)
    rng = np.random.default_rng(1)
    noise = (rng.standard_normal(w.size) + 1j * rng.standard_normal(w.size)) / np.sqrt(2)
    g = _five_modes(w)
    assert resonance_count(w, g) == 5
    assert resonance_count(w, g * (1 + 0.05 * noise)) == 5
    lowpass = 100 / (1j * w + 100)
    assert resonance_count(w, lowpass * (1 + 0.05 * noise)) == 0
    # heavy-tailed noise (Student t, 2 degrees of freedom, scale 10 %): without the running
    # median of 3 points, 9 isolated maxima stood out (at 10 times the noise's spread)
    t = rng.standard_t(2, (2, w.size)) * 0.1
    assert resonance_count(w, lowpass * (1 + t[0] + 1j * t[1])) == 0
    # points of weight 0 are left out: a hum on 5 points makes a peak unless weighted out
    hum = lowpass * np.where(np.abs(np.arange(w.size) - 500) <= 2, 10.0, 1.0)
    assert resonance_count(w, hum) == 1
    assert resonance_count(w, hum, np.where(hum != lowpass, 0.0, 1.0)) == 0
    assert resonance_count(w[:4], g[:4]) == 0


def test_the_search_does_not_stop_below_the_resonance_peaks():
    from freqid_casadi.fitting.order import OrderStep, decide

    # many-modes-3 of results/corpus-order (12 modes, 400 points, 0.45 % noise; 9 peaks
    # counted): RMS, roughness ratio and local-noise ratio of 1..13 sections. One section
    # is one mode of twelve: 4 -> 5 -> 6 lower the RMS by 9 % and 2 %, under the 10 % floor
    measured = [(0.8577, 4.17, 119.8), (0.8312, 4.08, 117.7), (0.8145, 4.42, 104.1),
                (0.7996, 3.97, 128.9), (0.7248, 5.47, 64.4), (0.7116, 5.17, 144.8),
                (0.3749, 2.84, 21.0), (0.3729, 2.84, 21.1), (0.0409, 1.43, 3.15),
                (0.0145, 1.1, 1.88), (0.0056, 0.98, 1.12), (0.0044, 0.98, 0.96),
                (0.0044, 0.98, 0.96)]
    steps = [OrderStep(n, rms, ratio, True, local_ratio=local)
             for n, (rms, ratio, local) in enumerate(measured, 1)]
    poles = [np.array([-1 + 10j, -1 - 10j])] * len(steps)
    omega = np.array([0.3, 1000.0])
    assert decide(steps[:6], poles[:6], omega, 400) == (4, "no-improvement")
    assert all(decide(steps[:k], poles[:k], omega, 400, peaks=9) is None
               for k in range(2, 13))
    assert decide(steps, poles, omega, 400, peaks=9) == (11, "consistent")
    # at or above the peaks the rule is the one before
    assert decide(steps[:6], poles[:6], omega, 400, peaks=6) == (4, "no-improvement")
    assert decide(steps[:6], poles[:6], omega, 400, peaks=7) is None


@pytest.mark.slow
def test_auto_order_on_a_twelve_mode_structure(monkeypatch):
    """many-modes-3 at 200 points (12 modes, 0.45 % noise; 9 resonance peaks counted).
    Measured: the search runs to 12 sections and keeps 11 (RMS 0.00508, the 12th mode
    within the noise), about 30 s; without the peaks it stopped at 3 sections (RMS 0.852,
    0.671, 0.634, 0.584: falls of 5.5 and 7.9 %, under the 10 % floor), calling the model
    class the limit."""
    from freqid_casadi.fitting import order
    from freqid_casadi.studies.corpus_order import many_mode_case

    c = many_mode_case(3, n_points=200)
    res = fc.fit(c.data, n_sections="auto")
    rec = next(d for d in res.diagnostics if d.code == "order-chosen")
    assert rec.values["resonance_peaks"] == 9 and "the data show 9 resonance peaks" in rec.message
    assert 11 <= res.model.n_sections <= 13 and rec.values["reason"] == "consistent"
    assert res.status == "ok" and res.rms_rel_error < FLOOR_FACTOR * c.noise
    monkeypatch.setattr(order, "resonance_count", lambda *args, **kwargs: 0)
    before = fc.fit(c.data, n_sections="auto")
    rec = next(d for d in before.diagnostics if d.code == "order-chosen")
    assert before.model.n_sections <= 4 and rec.values["reason"] == "no-improvement"
    assert before.rms_rel_error > 0.5


def test_the_search_issues_the_warnings_of_the_order_it_keeps_only():
    # an order's warnings concern its model: six ResolutionWarnings of orders the search
    # passed over reached a user of n_sections="auto" on a 12-mode structure
    w = np.logspace(-1, 1, 60)
    s = 1j * w
    data = fc.FrequencyData(w, 4 / (s * s + 0.4 * s + 4))

    def fit_one(n):
        warnings.warn(f"about the model of {n} sections", UserWarning)
        return fc.fit(data, n_sections=n, integrator=False)
    with warnings.catch_warnings(record=True) as issued:
        warnings.simplefilter("always")
        choice = choose_order(fit_one, max_sections=3)
    assert choice.n_sections == 1 and [s.n_sections for s in choice.steps] == [1, 2]
    assert [str(x.message) for x in issued] == ["about the model of 1 sections"]


def test_more_peaks_than_sections_tried_says_what_to_pass():
    from freqid_casadi.fitting.order import OrderStep, _choice

    steps = [OrderStep(n, 0.9 - 0.05 * n, 3.0, True) for n in (1, 2, 3)]
    poles = [np.array([-1 + 10j, -1 - 10j])] * 3
    choice = _choice([None] * 3, steps, poles, 2, "max-sections", np.array([1.0, 100.0]),
                     peaks=23)
    assert choice.peaks == 23
    assert choice.message.endswith(
        "the data show 23 resonance peaks, more than the 3 sections tried: pass "
        "n_sections=range(1, 24) (command line --max-sections 23), or fit a narrower band")


def test_a_larger_order_that_ended_worse_is_said_to_have_stopped_short():
    # a published line's S21: 10 sections at RMS 0.081 after 9 at 0.057, and the message
    # said the model class, not the order, limited the fit
    from types import SimpleNamespace

    from freqid_casadi.fitting.order import OrderStep, _choice

    steps = [OrderStep(9, 0.057, 3.0, True), OrderStep(10, 0.081, 3.0, True)]
    results = [SimpleNamespace(data=SimpleNamespace(weights=None), rms_rel_error=s.rms)
               for s in steps]
    omega = np.logspace(0, 2, 50)
    poles = [np.array([-1 + 10j, -1 - 10j])] * 2
    message = _choice(results, steps, poles, 0, "no-improvement", omega).message
    assert ("but the fit at 10 sections ended above this one's RMS, which a larger model "
            "cannot do at its optimum: that fit stopped short, so the order is not ruled "
            "out: fit n_sections=10 on its own, with start='best'") in message
    assert "the model class, not the order, limits this fit" not in message

"""The measured-data study (issue 15): the actuator from its raw records and the robot arm,
with the package's data only (no ../shared)."""

import numpy as np
import pytest

from freqid_casadi.studies import measured


@pytest.fixture(scope="module")
def study():
    return measured.run_measured()


def _ours(ds, n):
    (row,) = [r for r in ds.rows if r["method"] == "freqid" and r["n_sections"] == n]
    return row


def test_actuator_h1_band_from_the_raw_records(study):
    est = study.actuator.estimate
    f = est.data.omega / (2 * np.pi)
    assert f[0] < 0.13 and f[-1] > 19.5 and np.all(est.coherence >= 0.99)
    assert abs(abs(est.data.response[0]) - 1) < 0.02          # unit gain at low frequency


def test_actuator_two_sections_with_a_delay(study):
    row = _ours(study.actuator, 2)
    assert row["max_rel_error"] <= 0.03
    assert row["stable"] and row["minimum_phase"]


def test_actuator_two_sections_converges(study):
    # was: the polish stopped at its 200-iteration limit while a real pole crept to 0 in
    # the unit-DC chart (1771 iterations to converge); the monic/unit-linear charts of
    # stages.choose_charts put its limit at finite variables, on the root floor
    row = _ours(study.actuator, 2)
    assert row["success"] is True
    assert row["max_rel_error"] <= 0.03
    assert "root-below-band" in [d["code"] for d in row["diagnostics"]]


@pytest.mark.xfail(strict=True, reason="measured since the charts (issue 15): converged fits "
                   "give 7.00 ms at 2 sections (rational start; sequential 9.54) and 9.21 ms "
                   "at 3 (rational; sequential 9.47); the 6.61 ms at 3 sections before was "
                   "the rational polish stopped at its 200-iteration limit. Polishing the "
                   "2-section fit plus one section converges to 3-section optima with delays "
                   "6.96-15.6 ms within 4 % RMS of each other: at 3 sections the delay trades "
                   "with zeros above the band and these data do not determine it (its "
                   "covariance std is 1.2e3 s: the fit reports delay-undetermined)")
def test_actuator_delays_at_two_and_three_sections_agree(study):
    d2, d3 = _ours(study.actuator, 2)["delay"], _ours(study.actuator, 3)["delay"]
    assert abs(d2 - d3) <= 1e-3
    assert 0.003 < d2 < 0.012                                  # a few milliseconds


def test_actuator_beats_the_stable_peers_at_two_sections(study):
    ours = _ours(study.actuator, 2)
    stable_peers = [r for r in study.actuator.rows if r["method"] != "freqid"
                    and r["n_sections"] == 2 and r.get("stable")]
    assert stable_peers
    assert all(ours["max_rel_error"] <= r["max_rel_error"] for r in stable_peers)


def test_robot_arm_negative_gain_is_found_and_stated(study):
    for n in measured.ROBOT_ARM["sections"]:
        row = _ours(study.robot_arm, n)
        assert row["gain"] < 0
        assert "negative-gain" in [d["code"] for d in row["diagnostics"]]
    one = _ours(study.robot_arm, 1)
    assert "no-better-than-trivial" in [d["code"] for d in one["diagnostics"]]
    assert not one["success"]
    assert _ours(study.robot_arm, 5)["rms_rel_error"] < 0.1

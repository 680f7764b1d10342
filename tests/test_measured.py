"""The measured-data study: the actuator from its raw records and the robot arm,
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


def test_actuator_delays_at_two_and_three_sections_agree(study):
    # at 3 sections the free fit's delay (9.21 ms, rational start) trades against a zero
    # pair above the band (covariance std 1.2e3 s; 2-section fit + one section polishes to
    # optima with 6.96-15.6 ms within 4 % RMS): the fit states it (delay-undetermined) and
    # holds the delay at the 2-section fit's, kept because it converged within 10 % of the
    # free fit's max and RMS errors (measured: 0.0298 vs 0.0292, RMS 0.00733 vs 0.00725)
    two, three = _ours(study.actuator, 2), _ours(study.actuator, 3)
    assert two["success"] is True and three["success"] is True
    d2, d3 = two["delay"], three["delay"]
    assert abs(d2 - d3) <= 1e-3
    assert 0.003 < d2 < 0.012                                  # a few milliseconds
    assert two["delay_std"] < 0.5e-3 and three["delay_std"] < 2e-3
    assert two["max_rel_error"] <= 0.03
    (held,) = [d for d in three["diagnostics"] if d["code"] == "delay-undetermined"]
    assert held["values"]["held_from_n_sections"] == 2
    assert held["values"]["delay_free_std"] > 1.0              # the free fit's: undetermined
    assert three["max_rel_error"] <= 1.1 * held["values"]["max_rel_error_free"]
    assert three["rms_rel_error"] <= 1.1 * held["values"]["rms_rel_error_free"]
    assert "delay-undetermined" not in [d["code"] for d in two["diagnostics"]]


def test_actuator_one_section_delay_absorbs_the_unmodelled_lag(study):
    # "at 1 section the delay may absorb the unmodelled lag: say how much";
    # measured: 4.71 ms at 1 section, 7.00 ms at 2 (the 1-section model's zero far above
    # the band, 2.9e3 rad/s, and the missing second pole shift it by -2.3 ms)
    one, two = _ours(study.actuator, 1), _ours(study.actuator, 2)
    assert one["success"] is True and one["delay_std"] < 1e-3
    assert 1.5e-3 < two["delay"] - one["delay"] < 3e-3


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

"""The noisy-data and robot-arm studies (freqid_casadi.studies.noisy, .robot_arm) on small
problems: the report folder, its first line, and report.md's numbers against report.json."""

import json

import matplotlib

matplotlib.use("Agg")

import pytest  # noqa: E402

from freqid_casadi.errors import OptionError  # noqa: E402
from freqid_casadi.formatting import generated_by_line, number  # noqa: E402
from freqid_casadi.studies.noisy_report import write_noisy_report  # noqa: E402
from freqid_casadi.studies.robot_arm import choose  # noqa: E402
from freqid_casadi.studies.robot_arm_report import write_robot_arm_report  # noqa: E402


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    out = tmp_path_factory.mktemp("arm") / "robot_arm"
    summary = write_robot_arm_report(out, command="python scripts/robot_arm.py --orders 1,3",
                                     orders=(1, 3))
    return out, summary


def test_robot_arm_report(arm):
    out, s = arm
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["report.md", "report.json", "frf.csv", "bode.png", "rel_error.png",
         "error_vs_order.png", "pole_zero.png", "uncertainty_weight.png"])
    md = (out / "report.md").read_text(encoding="utf-8")
    assert md.splitlines()[0] == generated_by_line("python scripts/robot_arm.py --orders 1,3")
    assert json.loads((out / "report.json").read_text(encoding="utf-8")) == s
    # the rule picks 3 sections without delay (RMS 0.0916 against 0.98 at one section)
    p = s["chosen"]
    assert (p["n_sections"], p["delay"]) == (3, False)
    assert p["rms_rel_error"] == pytest.approx(0.0916, abs=5e-4)
    assert f"max relative error {number(p['max_rel_error'])}, RMS " \
           f"{number(p['rms_rel_error'])}" in md
    assert [(r["delay"], r["n_sections"]) for r in s["rows"]] == [
        (False, 1), (False, 3), (True, 1), (True, 3)]


def test_robot_arm_choice_rule():
    rows = [{"n_sections": n, "delay": d, "rms_rel_error": e}
            for n, d, e in ((1, False, 1.0), (2, True, 0.11), (2, False, 0.12), (3, False, 0.1))]
    pick, best = choose(rows, within=1.25)
    assert best == 0.1 and (pick["n_sections"], pick["delay"]) == (2, False)
    pick, _ = choose(rows, within=1.05)
    assert pick["n_sections"] == 3


def test_noisy_report_refuses_existing_folder(tmp_path):
    (tmp_path / "noisy").mkdir()
    with pytest.raises(OptionError, match="exists; pass --force"):
        write_noisy_report(tmp_path / "noisy", command="x", n_sections=1)


@pytest.mark.slow
def test_noisy_report_small(tmp_path):
    out = tmp_path / "noisy"
    s = write_noisy_report(out, command="python scripts/noisy_example.py --sections 3",
                           n_sections=3)
    assert sorted(p.name for p in out.iterdir()) == ["clean_error.png", "report.json",
                                                      "report.md", "weights.png"]
    md = (out / "report.md").read_text(encoding="utf-8")
    a = s["noisy"]
    assert a["n_sections"] == 3 and s["n_points"] == 500 and s["n_dense"] == 5000
    # the noise is the seeded 2 % realisation, measured
    assert s["noise_rms"] == pytest.approx(0.02, rel=0.1)
    assert f"RMS {number(s['noise_rms'])}, max |n| {number(s['noise_max'])}" in md
    assert s["weights_effect"] in md

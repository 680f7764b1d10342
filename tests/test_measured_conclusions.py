"""The measured report's conclusion on the delay counts only fits that determine it."""

from types import SimpleNamespace

from freqid_casadi.studies.measured_report import _conclusions


def _row(n, delay, std, success=True, codes=()):
    return {"method": "freqid", "n_sections": n, "order": 2 * n, "max_rel_error": 0.1,
            "rms_rel_error": 0.05, "delay": delay, "delay_std": std, "success": success,
            "diagnostics": [{"code": c, "message": "m"} for c in codes]}


def _delay_line(rows):
    return _conclusions(SimpleNamespace(name="robot arm", rows=rows))[-1]


def test_flagged_or_unconverged_delays_are_not_listed_as_determined():
    # the robot arm's published rows: 1 section not converged (explains nothing),
    # 2 sections std 0.017 <= half of 0.063 but the phase test says undetermined
    rows = [_row(1, 1.675, 0.45, success=False, codes=("no-better-than-trivial",)),
            _row(2, 0.06302, 0.017, codes=("negative-gain", "delay-undetermined")),
            _row(4, 0.6137, 0.43, codes=("delay-undetermined",))]
    assert _delay_line(rows).startswith("The data determine the delay at none")


def test_determined_delays_and_their_spread():
    rows = [_row(1, 4.707e-3, 0.48e-3), _row(2, 7.001e-3, 0.23e-3),
            _row(3, 7.001e-3, 1.5e-3, codes=("delay-undetermined",))]
    line = _conclusions(SimpleNamespace(name="actuator", rows=rows))[-1]
    assert line.startswith("Delays the data determine")
    assert "1 section(s) 4.707, 2 section(s) 7.001 ms" in line
    assert "3 section(s)" not in line and "spread 2.29 ms" in line


def test_a_single_determined_delay_is_named():
    rows = [_row(1, 2.0, 0.1), _row(2, 2.0, 5.0)]
    assert _delay_line(rows).startswith("Only the 1-section fit determines the delay")

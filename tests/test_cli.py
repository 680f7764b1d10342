"""Tests of the freqid command line: one-line errors with exit 2, reports, progress."""

import json
import os
import subprocess
import sys

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from freqid_casadi.report.outputs import MARKER  # noqa: E402
from freqid_casadi.cli import app as cli  # noqa: E402
import freqid_casadi as fc  # noqa: E402
from freqid_casadi.report import folder as report  # noqa: E402
from freqid_casadi.core.data import FrequencyData  # noqa: E402
from freqid_casadi.io.loaders import save_csv  # noqa: E402
from freqid_casadi.fitting.fit import fit  # noqa: E402
from freqid_casadi.core.model import RationalDelayModel, Structure  # noqa: E402

# a known model: 2 sections, integrator, delay 0.01 s; 60 points from 0.1 to 100 rad/s
_BETA = [0.01, 4.0, 1, 0.05, 3.0, 1, 0.02, 2.0, 1, 0.03, 30.0, 1, 0.01, 20.0]
_OMEGA = np.logspace(-1, 2, 60)


def _plant():
    model = RationalDelayModel(Structure(2, integrator=True), np.array(_BETA))
    return model, FrequencyData(_OMEGA, model.frequency_response(_OMEGA), "plant")


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    """A cwd holding plant.csv (the known model's response)."""
    monkeypatch.chdir(tmp_path)
    save_csv(_plant()[1], "plant.csv")
    return tmp_path


@pytest.fixture(scope="module")
def cached_result():
    return fit(_plant()[1], n_sections=2, integrator=True)


@pytest.fixture
def fake_fit(monkeypatch, cached_result):
    """Replace the fit by the cached result and record the call's arguments."""
    calls = []

    def fake(data, **kwargs):
        calls.append((data, kwargs))
        return cached_result

    monkeypatch.setattr(cli, "fit", fake)
    return calls


@pytest.fixture
def fast_figures(monkeypatch):
    def write(result, folder, summary, truth=None):
        for name in ("bode.png", "rel_error.png", "pole_zero.png", "stages.png"):
            with open(os.path.join(folder, name), "wb") as fh:
                fh.write(b"\x89PNG placeholder")

    monkeypatch.setattr(report, "_write_figures", write)


def run(capsys, *argv):
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def _assert_one_error_line(err, match):
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: "), err
    assert match in lines[0], err
    assert "Traceback" not in err


# ----------------------------------------------------------------------------- bad input


def _bad_header(p):
    p.write_text("freq,re,im\n1,2,3\n")


def _bad_cell(p):
    p.write_text("omega,real,imag\n1,2,3\n2,x,4\n")


@pytest.mark.parametrize("argv, match", [
    (["fit", "missing.csv", "--sections", "2", "--out", "rep"], "not found"),
    (["fit", "adir", "--sections", "2", "--out", "rep"], "is a directory"),
    (["fit", "header.csv", "--sections", "2", "--out", "rep"], "unrecognised header"),
    (["fit", "cell.csv", "--sections", "2", "--out", "rep"], "'x' is not a number"),
    (["fit", "plant.csv", "--sections", "0", "--out", "rep"], "--sections"),
    (["fit", "plant.csv", "--sections", "-3", "--out", "rep"], "positive integer"),
    (["fit", "plant.csv", "--sections", "two", "--out", "rep"], "positive integer"),
    (["fit", "plant.csv", "--sections", "2", "--method", "newton", "--out", "rep"],
     "invalid choice: 'newton'"),
    (["fit", "plant.csv", "--sections", "2", "--basis", "third-order", "--out", "rep"],
     "invalid choice: 'third-order'"),
    (["fit", "plant.csv", "--sections", "2", "--tol", "-1", "--out", "rep"], "--tol"),
    (["fit", "plant.csv", "--sections", "2", "--tol", "nan", "--out", "rep"], "--tol"),
    (["fit", "plant.csv", "--sections", "2"], "--out"),
    (["fit", "plant.csv", "--sections", "40", "--out", "rep"], "sections"),
    (["fit", "plant.csv", "--sections", "2", "--out", "nodir/rep"], "does not exist"),
    (["example", "D"], "invalid choice: 'D'"),
    (["example", "A", "--sections", "0"], "positive integer"),
    (["frobnicate"], "invalid choice"),
    ([], "required"),
    (["fit", "plant.csv", "--sections", "2", "--out", "rep", "--quiet", "--progress"],
     "not allowed"),
])
def test_bad_input_is_one_error_line_and_exit_2(workdir, capsys, argv, match):
    (workdir / "adir").mkdir()
    _bad_header(workdir / "header.csv")
    _bad_cell(workdir / "cell.csv")
    before = sorted(os.listdir(workdir))
    code, out, err = run(capsys, *argv)
    assert code == 2
    _assert_one_error_line(err, match)
    assert out == ""
    assert sorted(os.listdir(workdir)) == before        # no report, no temporary folder


def test_existing_out_is_refused_before_fitting(workdir, capsys, fake_fit):
    (workdir / "rep").mkdir()
    (workdir / "rep" / "keep.txt").write_text("old")
    code, out, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--out", "rep")
    assert code == 2
    _assert_one_error_line(err, "output folder 'rep' exists; pass --force")
    assert fake_fit == []                                 # no fit was wasted
    assert os.listdir(workdir / "rep") == ["keep.txt"]
    code, out, err = run(capsys, "example", "B", "--out", "rep")
    assert code == 2 and fake_fit == []
    _assert_one_error_line(err, "exists")


def test_force_replaces(workdir, capsys, fake_fit, fast_figures):
    (workdir / "rep").mkdir()
    (workdir / "rep" / "keep.txt").write_text("old")
    (workdir / "rep" / MARKER).write_text("")        # a folder freqid wrote
    code, out, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--integrator",
                         "--out", "rep", "--force")
    assert code == 0, err
    assert sorted(os.listdir(workdir / "rep")) == sorted(report.REPORT_FILES)
    assert sorted(os.listdir(workdir)) == ["plant.csv", "rep"]


# ----------------------------------------------------------------------------- success


def test_fit_writes_a_report(workdir, capsys):
    argv = ["fit", "plant.csv", "--sections", "2", "--integrator", "--out", "rep"]
    code, out, err = run(capsys, *argv)
    assert code == 0, err
    assert err == ""                                     # stderr is not a terminal
    rep = workdir / "rep"
    assert sorted(os.listdir(rep)) == sorted(report.REPORT_FILES)
    for name in report.REPORT_FILES:
        assert (rep / name).stat().st_size > 0
    md = (rep / "summary.md").read_text(encoding="utf-8")
    assert md.splitlines()[0] == "<!-- generated by: freqid " + " ".join(argv) + " -->"
    summary = json.loads((rep / "summary.json").read_text(encoding="utf-8"))
    assert summary["command"] == "freqid " + " ".join(argv)
    # the known model is recovered
    assert summary["max_rel_error"] < 1e-6
    assert abs(summary["delay"] - 0.01) < 1e-8
    assert summary["structure"] == {"n_sections": 2, "basis": "second-order",
                                    "integrator": True, "delay": True,
                                    "order_rational_part": 4, "order": 5}
    # the numbers of the Markdown are those of the JSON
    for key in ("max_rel_error", "rms_rel_error", "wall_time"):
        assert f"{summary[key]:.4g}" in md
    assert f"{summary['delay']:.6g} s" in md
    assert "plant: 2 sections (order 5)" in out
    assert out.strip().splitlines()[-1] == f"report: {rep}"


def test_progress_flags(workdir, capsys, fake_fit, fast_figures):
    assert run(capsys, "fit", "plant.csv", "--sections", "2", "--out", "r1")[0] == 0
    assert run(capsys, "fit", "plant.csv", "--sections", "2", "--out", "r2",
               "--progress")[0] == 0
    assert run(capsys, "fit", "plant.csv", "--sections", "2", "--out", "r3",
               "--quiet")[0] == 0
    # default: a bar on a terminal, silent in a pipe; --progress: a line per stage always
    assert [kw["progress"] for _, kw in fake_fit] == [True, "lines", False]


def test_fit_options_are_passed(workdir, capsys, fake_fit, fast_figures):
    code, _, err = run(capsys, "fit", "plant.csv", "--sections", "3", "--no-delay",
                       "--basis", "first-order", "--method", "barrier-lm", "--tol", "1e-3",
                       "--out", "rep")
    assert code == 0, err
    data, kw = fake_fit[0]
    assert data.name == "plant" and data.n_points == _OMEGA.size
    assert kw == dict(n_sections=3, integrator="auto", delay=False, basis="first-order",
                      method="barrier-lm", tol=1e-3, progress=True, start="best",
                      objective="least-squares", min_damping=None, gain_sign="auto",
                      zeros="minimum-phase")


def test_fit_loop_switches_are_options(workdir, capsys, fake_fit, fast_figures):
    # the guard's and the delay hold's messages named LoopOptions(...) on the command line
    code, _, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--no-resolution-guard",
                       "--no-hold-delay", "--out", "rep")
    assert code == 0, err
    assert fake_fit[0][1]["loop"] == fc.LoopOptions(resolution_guard=False, hold_delay=False)
    code, _, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--no-hold-delay",
                       "--out", "rep2")
    assert fake_fit[1][1]["loop"] == fc.LoopOptions(hold_delay=False)
    code, _, err = run(capsys, "example", "A", "--no-resolution-guard", "--out", "rep3")
    assert code == 0 and fake_fit[2][1]["loop"] == fc.LoopOptions(resolution_guard=False)
    from freqid_casadi.cli.common import cli_words

    assert cli_words("refit kept; pass loop=LoopOptions(resolution_guard=False) to keep the "
                     "free fit (FitResult.alternatives['min_damping=None'] holds it)") == \
        "refit kept; pass --no-resolution-guard to keep the free fit"
    assert cli_words("held (RMS 0.1); LoopOptions(hold_delay=False) keeps the free fit") == \
        "held (RMS 0.1); --no-hold-delay keeps the free fit"


def test_fit_min_damping_option(workdir, capsys, fake_fit, fast_figures):
    code, _, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--min-damping", "auto",
                       "--out", "rep")
    assert code == 0, err
    assert fake_fit[0][1]["min_damping"] == "auto"
    code, _, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--min-damping", "0.02",
                       "--out", "rep2")
    assert code == 0, err
    assert fake_fit[1][1]["min_damping"] == 0.02
    for bad in ("-1", "1.5", "lots", "nan"):
        code, out, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--min-damping",
                             bad, "--out", "rep3")
        assert code == 2 and err.startswith("error:") and "--min-damping" in err
        assert "Traceback" not in err


@pytest.mark.parametrize("method, options", [("ipopt", fc.IpoptOptions),
                                             ("barrier-lm", fc.BarrierLMOptions)])
def test_fit_final_max_iter_option(workdir, capsys, fake_fit, fast_figures, method, options):
    code, _, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--method", method,
                       "--final-max-iter", "2000", "--out", "rep")
    assert code == 0, err
    assert fake_fit[0][1]["method"] == options(final_max_iter=2000)
    code, _, err = run(capsys, "example", "B", "--method", method, "--final-max-iter", "300",
                       "--out", "rep_example")
    assert code == 0, err
    assert fake_fit[1][1]["method"] == options(final_max_iter=300)
    for bad in ("0", "-5", "2.5", "many"):
        code, _, err = run(capsys, "fit", "plant.csv", "--sections", "2",
                           "--final-max-iter", bad, "--out", "rep2")
        assert code == 2 and err.startswith("error:") and "--final-max-iter" in err
        assert "Traceback" not in err


def test_fit_at_its_iteration_limit_says_which_option_continues_it(
        workdir, capsys, monkeypatch, cached_result, fast_figures):
    """The fit's message names the Python option (method=IpoptOptions(final_max_iter=N));
    the command adds the same advice as its own option."""
    import dataclasses

    stopped = dataclasses.replace(cached_result, message=(
        "not-converged: the final stage reached its iteration limit (200) ... — pass "
        "method=IpoptOptions(final_max_iter=2000) to continue"))
    monkeypatch.setattr(cli, "fit", lambda data, **kwargs: stopped)
    code, out, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--out", "rep")
    assert code == 0, err
    assert "to continue: run the same command with --final-max-iter 2000" in out
    code, out, err = run(capsys, "example", "A", "--out", "rep_example")
    assert code == 0, err
    assert "to continue: run the same command with --final-max-iter 2000" in out
    monkeypatch.setattr(cli, "fit", lambda data, **kwargs: cached_result)
    code, out, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--out", "rep2")
    assert code == 0 and "--final-max-iter" not in out


def test_fit_prints_its_advice_as_the_commands_options(workdir, capsys, monkeypatch,
                                                       cached_result, fast_figures):
    """A fit's message advises in fit's keywords; the command prints its own options."""
    import dataclasses

    advised = dataclasses.replace(cached_result, message=(
        "poor-fit: converged, but ...; pass integrator=-1 or integrator=False if you know it; "
        "pass gain_sign='positive'; the data need right-half-plane zeros: zeros='free' "
        "reaches RMS 0.02 at 3 sections — pass zeros='free' (FitResult.alternatives"
        "['zeros=free']); pass n_sections=2 or more (or min_damping='auto' if that feature "
        "is noise) — pass method=IpoptOptions(final_max_iter=2000) to continue"))
    monkeypatch.setattr(cli, "fit", lambda data, **kwargs: advised)
    code, out, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--out", "rep")
    assert code == 0, err
    assert ("pass --integrator -1 or --integrator 0 if you know it; pass --gain-sign "
            "positive; the data need right-half-plane zeros: --zeros free reaches RMS 0.02 at "
            "3 sections — pass --zeros free; pass --sections 2 or more (or --min-damping "
            "auto if that feature is noise) — pass --final-max-iter 2000 to continue") in out
    assert "FitResult" not in out and "IpoptOptions" not in out
    # every option it names parses: the advice runs as printed
    code, _, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--integrator", "0",
                       "--gain-sign", "positive", "--zeros", "free", "--min-damping", "auto",
                       "--final-max-iter", "2000", "--out", "rep2")
    assert code == 0, err
    # freqid example words it the same way (it printed n_sections=10, min_damping='auto'),
    # and takes the --sections and --min-damping it names
    code, out, err = run(capsys, "example", "B", "--out", "rep3")
    assert code == 0 and "pass --sections 2 or more (or --min-damping auto" in out, out
    assert "FitResult" not in out and "IpoptOptions" not in out
    code, _, err = run(capsys, "example", "B", "--sections", "10", "--min-damping", "auto",
                       "--out", "rep4")
    assert code == 0, err


@pytest.mark.parametrize("name, n_sections, integrator, delay, basis", [
    ("A", 17, True, True, "second-order"),
    ("B", 9, False, True, "second-order"),
    ("C", 27, True, True, "second-order"),
    ("fractional", cli.FRACTIONAL_SECTIONS, False, False, "first-order"),
])
def test_example_settings(workdir, capsys, fake_fit, fast_figures, cached_result, name,
                          n_sections, integrator, delay, basis):
    code, out, err = run(capsys, "example", name)
    assert code == 0, err
    data, kw = fake_fit[0]
    assert (kw["n_sections"], kw["integrator"], kw["delay"], kw["basis"]) == \
        (n_sections, integrator, delay, basis)
    assert data.n_points == 500
    folder = workdir / f"freqid_example_{name}"
    assert sorted(os.listdir(folder)) == sorted(report.REPORT_FILES)
    md = (folder / "summary.md").read_text(encoding="utf-8")
    assert md.startswith(f"<!-- generated by: freqid example {name} -->\n")
    # the status line first (the fake fit's message), then the table
    assert out.splitlines()[0] == cached_result.message
    assert out.splitlines()[0].startswith(cached_result.status.value + ":")
    assert kw["start"] == "sequential"            # the thesis's loop, stated
    assert out.splitlines()[1].split()[:2] == ["example", "order"]
    assert out.strip().splitlines()[-1] == f"report: {folder}"


def test_example_prints_the_thesis_numbers(workdir, capsys, fake_fit, fast_figures):
    code, out, _ = run(capsys, "example", "A", "--sections", "2", "--out", "exA")
    assert code == 0
    assert fake_fit[0][1]["n_sections"] == 2
    row = out.splitlines()[3].split()
    assert row[:2] == ["A", "4"]
    assert row[-3:] == ["34", "0.2549", "0.0106"]
    md = (workdir / "exA" / "summary.md").read_text(encoding="utf-8")
    assert "## Thesis vs ours" in md and "0.2549" in md


# ----------------------------------------------------------------------------- interrupts


def _interrupt(*args, **kwargs):
    raise KeyboardInterrupt


def test_interrupted_fit(workdir, capsys, monkeypatch):
    monkeypatch.setattr(cli, "fit", _interrupt)
    code, out, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--out", "rep")
    assert code == 130
    assert err == "error: interrupted\n"
    assert sorted(os.listdir(workdir)) == ["plant.csv"]


def test_interrupted_report(workdir, capsys, fake_fit, monkeypatch):
    monkeypatch.setattr(report, "_write_rel_error_csv", _interrupt)
    code, out, err = run(capsys, "example", "A", "--out", "rep")
    assert code == 130 and err == "error: interrupted\n"
    assert sorted(os.listdir(workdir)) == ["plant.csv"]


def test_os_error_while_writing(workdir, capsys, fake_fit, monkeypatch):
    def fail(*args, **kwargs):
        raise OSError(28, "No space left on device", "rel_error.csv")

    monkeypatch.setattr(report, "_write_rel_error_csv", fail)
    code, out, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--out", "rep")
    assert code == 2
    _assert_one_error_line(err, "No space left on device")
    assert sorted(os.listdir(workdir)) == ["plant.csv"]


# ----------------------------------------------------------------------------- entry point


def test_python_m_help():
    proc = subprocess.run([sys.executable, "-m", "freqid_casadi", "--help"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("usage: freqid")
    assert "example" in proc.stdout and "fit" in proc.stdout


def test_notes_of_many_files_are_printed_once_per_text(capsys):
    import warnings as _w

    from freqid_casadi.cli.common import grouped_notes, notes_to_stderr
    from freqid_casadi.io.loaders import DataWarning

    texts = [f"'H{i}.txt' is not UTF-8 (byte 0xb2 on line 9): read as Windows-1252"
             for i in range(1, 10)] + ["'H1.txt': band [65, 1000] Hz: kept 10 of 12 points"]
    assert grouped_notes(texts) == [
        "'H1.txt' ... 'H9.txt' (each of 9 files) is not UTF-8 (byte 0xb2 on line 9): read "
        "as Windows-1252", "'H1.txt': band [65, 1000] Hz: kept 10 of 12 points"]
    assert grouped_notes(["'a': x", "'b': x"]) == ["'a', 'b' (each of 2 files): x"]
    # the records of one UFF file: one file, several records
    assert grouped_notes(["'t.unv': x"] * 3) == ["'t.unv' (each of 3 responses): x"]
    assert grouped_notes(["'a': x", "'a': x", "'b': x"]) == ["'a', 'b' (each of 2 files): x"]
    with notes_to_stderr():                       # nested blocks: the outer one prints
        for t in texts[:3]:
            with notes_to_stderr():
                _w.warn(t, DataWarning)
    err = capsys.readouterr().err.splitlines()
    assert err == ["note: 'H1.txt', 'H2.txt', 'H3.txt' (each of 3 files) is not UTF-8 (byte "
                   "0xb2 on line 9): read as Windows-1252"]


def test_report_records_how_the_data_were_read(workdir, capsys, fake_fit, fast_figures):
    # an analyser's export: a preamble of metadata above the header; the note printed on
    # stderr is also the report's (a reader of summary.md sees how the file was taken)
    text = open("plant.csv").read()
    with open("export.csv", "w") as fh:
        fh.write("Instrument: Analyzer 9\nDate: 2026-12-07\n" + text)
    code, _, err = run(capsys, "fit", "export.csv", "--sections", "2", "--out", "rep")
    assert code == 0, err
    notes = [t[len("note: "):] for t in err.splitlines() if t.startswith("note: ")]
    assert len(notes) == 1 and "skipped 2 line(s) of metadata" in notes[0], err
    summary = json.load(open("rep/summary.json"))
    assert summary["data"]["read_notes"] == notes
    md = open("rep/summary.md").read()
    assert "## How the data were read\n\n- 'export.csv': skipped 2 line(s)" in md
    # a file read without a note: no such section, no key
    code, _, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--out", "rep2")
    assert code == 0 and "note:" not in err, err
    assert "read_notes" not in json.load(open("rep2/summary.json"))["data"]
    assert "How the data were read" not in open("rep2/summary.md").read()


def test_sweep_target_line_says_when_the_order_meeting_it_did_not_converge(
        workdir, capsys, monkeypatch):
    # a Siglent export swept 2:8:2 with --target 1e-2: "smallest order ... : 4" where order
    # 4's fit had stopped at its iteration limit; the line now says so
    from freqid_casadi.fitting import sweep as sweep_module
    from freqid_casadi.report import folder

    rows = tuple(sweep_module.SweepRow(
        order=o, n_sections=o // 2, max_rel_error=e, rms_rel_error=e / 2,
        max_rel_error_dense=e, delay=0.0, wall_time=1.0, success=st == "ok", start="rational",
        status=fc.FitStatus(st))
        for o, e, st in ((2, 0.05, "ok"), (4, 0.008, "not-converged"), (6, 0.007, "ok")))
    monkeypatch.setattr(sweep_module, "sweep", lambda data, orders, **kw: sweep_module.
                        SweepResult(rows=rows, target=kw["target"], best_order=4,
                                    data_name="plant"))
    monkeypatch.setattr(folder, "write_sweep_report", lambda result, out, **kw: str(out))
    code, out, err = run(capsys, "sweep", "plant.csv", "--orders", "2:6:2", "--target",
                         "1e-2", "--out", "rep", "--quiet")
    assert code == 0, err
    assert ("smallest order with max rel. error <= 0.01: 4 (status not-converged: its error "
            "is measured, the fit did not converge)") in out


def test_the_report_a_command_writes_gives_its_advice_as_options(workdir, capsys, monkeypatch,
                                                                   cached_result):
    # summary.md said "pass method=IpoptOptions(final_max_iter=2000)" beside a command line
    import dataclasses

    from freqid_casadi.fitting.diagnostics import Diagnostic

    advised = dataclasses.replace(cached_result, message=(
        "not-converged: ... — pass method=IpoptOptions(final_max_iter=2000) to continue"),
        diagnostics=(Diagnostic("poor-fit", "pass n_sections=3 or more", "warning", {}),))
    monkeypatch.setattr(cli, "fit", lambda data, **kwargs: advised)
    code, out, err = run(capsys, "fit", "plant.csv", "--sections", "2", "--out", "rep")
    assert code == 0, err
    md = open("rep/summary.md").read()
    assert "pass --final-max-iter 2000 to continue" in md and "IpoptOptions" not in md
    assert "pass --sections 3 or more" in md
    s = json.load(open("rep/summary.json"))
    assert s["message"].endswith("pass --final-max-iter 2000 to continue")
    assert "to continue: run the same command with --final-max-iter 2000" in out

"""Adversarial command lines (fuzz pass): what tests/test_hostile.py did not cover yet.

- ``--force`` on a user's folder that holds a copied report: the folder counted as "a
  report from before the marker" (a ``*.md`` with the generated-by first line) and was
  deleted with the user's other files in it (``thesis.docx``, ``sub/data.dat``).
- SIGHUP (the terminal closed) while a report was written left the temporary folder
  ``.<out>.tmp-*`` behind (the default action kills the process without clean-up).
- ``freqid frf --fs 1e300`` failed with "no frequency has coherence >= None (highest 0)".
- ``freqid frf --force`` overwrote a user's file named like its sidecar ``<stem>.stats.csv``
  and left an earlier run's sidecar beside an FRF it did not belong to.
- ``freqid batch --jobs 2`` printed the workers' warnings in Python's raw format.
- The report API: ``force="no"`` (truthy) replaced a report; ``out_dir=None`` or a
  result of None raised TypeError/AttributeError; ``model.save(folder)`` made a temporary
  file in the folder's parent and named it in the error.
"""

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from freqid_casadi.report import outputs as _outputs
from freqid_casadi.cli import app as cli
from freqid_casadi.report import folder as report
from freqid_casadi.core.data import FrequencyData
from freqid_casadi.io.loaders import load, save_csv
from freqid_casadi.core.model import RationalDelayModel, Structure
from test_hostile import snapshot  # one snapshot of a tree for both files
from conftest import one_section_model  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MODEL = one_section_model()
W = np.logspace(-1, 2, 40)


@pytest.fixture
def ws(tmp_path, monkeypatch):
    """cwd with plant.csv, a finished report ``rep/`` and a user's folder ``notes/`` that
    holds a copy of the report's summary.md beside the user's own files."""
    save_csv(FrequencyData(W, MODEL.frequency_response(W), "plant"), tmp_path / "plant.csv")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(report, "_write_figures", lambda *a, **k: None, raising=False)
    assert cli.main(["fit", "plant.csv", "--sections", "1", "--out", "rep", "--quiet"]) == 0
    notes = tmp_path / "notes"
    (notes / "sub").mkdir(parents=True)
    (notes / "summary.md").write_bytes((tmp_path / "rep" / "summary.md").read_bytes())
    (notes / "thesis.docx").write_text("precious")
    (notes / "sub" / "data.dat").write_text("measured")
    return tmp_path


def _run(capsys, *argv):
    code = cli.main(list(argv))
    return code, capsys.readouterr().err


@pytest.mark.parametrize("extra, needle", [
    ((), "it holds 'sub/data.dat'"),
    (("sub",), "it holds 'thesis.docx'"),           # sub/ removed: the .docx protects it
])
def test_force_keeps_a_users_folder_with_a_copied_report(ws, capsys, extra, needle):
    for name in extra:
        for p in (ws / "notes" / name).iterdir():
            p.unlink()
        (ws / "notes" / name).rmdir()
    before = snapshot(ws)
    code, err = _run(capsys, "fit", "plant.csv", "--sections", "1", "--out", "notes",
                     "--force", "--quiet")
    assert code == 2
    assert err.startswith("error: refusing to replace output folder 'notes': it was not "
                          "written by freqid") and needle in err, err
    assert snapshot(ws) == before


def test_force_still_replaces_an_old_report_without_the_marker(ws, capsys):
    legacy = ws / "old_report"
    legacy.mkdir()
    for name in ("summary.md", "summary.json", "rel_error.csv"):
        (legacy / name).write_bytes((ws / "rep" / name).read_bytes())
    assert _outputs.is_package_folder(legacy)
    assert not _outputs.is_package_folder(ws / "notes")
    assert _outputs.foreign_entry(legacy) is None
    code, err = _run(capsys, "fit", "plant.csv", "--sections", "1", "--out", "old_report",
                     "--force", "--quiet")
    assert code == 0, err
    assert _outputs.MARKER in os.listdir(legacy)


_HUNG_UP = """
import os, signal, sys, time
from freqid_casadi.cli import app as cli
from freqid_casadi.report import folder as report
signal.signal(signal.SIGHUP, signal.SIG_DFL)       # as in a terminal (not under nohup)
report._write_figures = lambda *a, **k: None

def hung_up(*a, **k):
    os.kill(os.getpid(), signal.SIGHUP)
    time.sleep(5)                                  # the handler raises before this ends

report.render_fit_summary = hung_up
sys.exit(cli.main(["fit", "plant.csv", "--sections", "1", "--out", "rep", "--force",
                   "--quiet"]))
"""


def test_sighup_while_writing_keeps_the_old_report(ws):
    # in a subprocess: before the fix SIGHUP killed the process (and would kill pytest)
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH",
                                                                               ""))
    before = snapshot(ws)
    proc = subprocess.run([sys.executable, "-c", _HUNG_UP], cwd=ws, env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 129, (proc.returncode, proc.stderr)
    assert proc.stderr.splitlines() == ["error: interrupted"]
    assert snapshot(ws) == before                  # old report kept, no .rep.tmp-* left


def test_sighup_ignored_by_nohup_stays_ignored(ws, capsys, monkeypatch):
    old = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        code, err = _run(capsys, "fit", "plant.csv", "--sections", "1", "--out", "rep2",
                         "--quiet")
        assert code == 0, err
        assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGHUP, old)


def test_frf_at_an_extreme_sampling_frequency(ws, capsys):
    rng = np.random.default_rng(0)
    u = rng.standard_normal(2048)
    y = np.convolve(u, [0.5, 0.3, 0.1])[:2048]
    (ws / "rec.csv").write_text("u,y\n" + "".join(f"{float(a)!r},{float(b)!r}\n"
                                                   for a, b in zip(u, y)))
    code, err = _run(capsys, "frf", "rec.csv", "--estimator", "h1", "--fs", "1e300",
                     "--nperseg", "256", "--out", "frf.csv")
    assert code == 0, err
    data = load(ws / "frf.csv")
    assert data.n_points == 128 and np.all(np.isfinite(data.response))
    assert data.omega[0] == pytest.approx(2 * np.pi * 1e300 / 256, rel=1e-12)


def _records(path, periods):
    """u,y records of a multisine (bins 1..3) through a first-order lag, 16 samples/period."""
    n = np.arange(16 * periods)
    u = sum(np.cos(2 * np.pi * k * n / 16 + k) for k in (1, 2, 3))
    y = np.zeros_like(u)
    for i in range(1, u.size):
        y[i] = 0.7 * y[i - 1] + 0.3 * u[i - 1]
    path.write_text("u,y\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(u, y)))


def test_frf_force_keeps_a_users_file_named_like_the_sidecar(ws, capsys):
    # before: --force on mine.csv overwrote the user's mine.stats.csv (never named by them)
    _records(ws / "rec.csv", 4)
    (ws / "mine.stats.csv").write_text("my own statistics\n")
    before = snapshot(ws)
    code, err = _run(capsys, "frf", "rec.csv", "--period", "16", "--out", "mine.csv",
                     "--force")
    assert code == 2
    assert "refusing to replace 'mine.stats.csv'" in err and "not written by freqid" in err
    assert snapshot(ws) == before


def test_frf_force_removes_its_own_stale_sidecar(ws, capsys):
    # before: a one-period FRF written over a four-period one kept the old statistics
    # beside it, which belonged to another estimate
    _records(ws / "rec.csv", 4)
    _records(ws / "rec1.csv", 1)
    assert _run(capsys, "frf", "rec.csv", "--period", "16", "--out", "f.csv")[0] == 0
    assert (ws / "f.stats.csv").is_file()
    code, err = _run(capsys, "frf", "rec1.csv", "--period", "16", "--out", "f.csv",
                     "--force")
    assert code == 0, err
    assert (ws / "f.csv").is_file() and not (ws / "f.stats.csv").exists()


def test_batch_worker_warnings_are_warning_lines(ws):
    # before: with --jobs 2 the workers printed Python's raw warnings on stderr
    # (".../batch.py:111: ResolutionWarning: ...", then the source line)
    # a 0.02 %-damped mode on a grid 20x coarser than its bandwidth: the fit keeps the
    # narrow pole the data determine (the damping floor cannot explain the peak) and warns
    (ws / "in").mkdir()
    w = np.logspace(0, 2, 100)
    s = 1j * w
    g = 1.0 / (s * s / 30.0 ** 2 + 2 * 2e-4 * s / 30.0 + 1) / (s / 60.0 + 1)
    rng = np.random.default_rng(3)
    g = g * (1 + 1e-3 * (rng.standard_normal(w.size) + 1j * rng.standard_normal(w.size)))
    for name in ("p1", "p2"):
        save_csv(FrequencyData(w, g, name), ws / "in" / f"{name}.csv")
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH",
                                                                               ""),
               MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, "-m", "freqid_casadi", "batch", "in", "--sections",
                           "2", "--no-delay", "--jobs", "2", "--out", "b"], cwd=ws, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.splitlines()
    assert lines and all(x.startswith("warning: ") for x in lines), proc.stderr
    assert any(x.startswith("warning: p1: the model has") for x in lines), proc.stderr
    assert "ResolutionWarning" not in proc.stderr and "batch.py" not in proc.stderr


# ----------------------------------------------------------------------- report API
@pytest.fixture
def fitted():
    import warnings

    import freqid_casadi as fc

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fc.fit(W, MODEL.frequency_response(W), n_sections=1)


def test_report_force_must_be_a_bool(ws, fitted):
    # before: force="no" is truthy and replaced the existing report
    from freqid_casadi.errors import OptionError

    before = snapshot(ws)
    with pytest.raises(OptionError, match="force must be True or False, got 'no'"):
        report.write_fit_report(fitted, "rep", command="x", force="no")
    assert snapshot(ws) == before


@pytest.mark.parametrize("out, needle", [
    (None, "must be a path .str or os.PathLike., got NoneType"),
    (3, "must be a path .str or os.PathLike., got int"),
])
def test_report_folder_must_be_a_path(ws, fitted, out, needle):
    # before: TypeError "expected str, bytes or os.PathLike object"
    from freqid_casadi.errors import OptionError

    with pytest.raises(OptionError, match=needle):
        report.write_fit_report(fitted, out, command="x")


def test_report_of_no_result_is_an_option_error(ws):
    # before: AttributeError 'NoneType' object has no attribute 'model' / 'as_dict'
    from freqid_casadi.errors import OptionError

    with pytest.raises(OptionError, match="result must be a FitResult"):
        report.write_fit_report(None, "r1", command="x")
    with pytest.raises(OptionError, match="result must be a SweepResult"):
        report.write_sweep_report(None, "r2", command="x")


def test_save_onto_a_folder_names_the_folder_and_makes_no_temporary_file(ws):
    # before: "[Errno 21] Is a directory: '<parent>/.tmp-xxxx' -> 'rep'", after a temporary
    # file was created in the parent folder
    before = snapshot(ws)
    with pytest.raises(IsADirectoryError, match="is a folder; give a file name inside it"):
        MODEL.save(ws / "rep")
    with pytest.raises(FileNotFoundError, match="its folder does not exist"):
        MODEL.save(ws / "nothere" / "m.json")
    assert snapshot(ws) == before


@pytest.mark.parametrize("argv", [
    ("fit", "plant.csv", "--sections", "1", "--out", "plant.csv/rep"),
    ("frf", "rec.csv", "--period", "16", "--out", "plant.csv/frf.csv"),
])
def test_out_under_a_file_says_the_parent_is_a_file(ws, capsys, argv):
    # before: "its parent folder '.../plant.csv' does not exist", no word of the file
    _records(ws / "rec.csv", 4)
    before = snapshot(ws)
    code, err = _run(capsys, *argv)
    assert code == 2
    assert "plant.csv' does not exist (a file has that name)" in err, err
    assert snapshot(ws) == before


def test_ctrl_c_between_the_two_renames_of_force_keeps_a_report_in_place(ws, monkeypatch):
    # before: a SIGINT right after the old report was moved aside raised before the new one
    # was renamed into place: 'rep' was gone, the old report hidden in '.rep.old-*'
    real_rename = os.rename
    calls = []

    def rename(src, dst):
        real_rename(src, dst)
        calls.append(os.path.basename(dst))
        if len(calls) == 1 and os.path.basename(dst).startswith(".rep.old-"):
            os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(_outputs.os, "rename", rename)
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            with _outputs.building("rep", force=True) as (tmp, path):
                (Path(tmp) / "summary.md").write_text("new report\n")
    finally:
        signal.signal(signal.SIGINT, old)
    assert (ws / "rep" / "summary.md").read_text() == "new report\n"
    assert [n for n in os.listdir(ws) if n.startswith(".rep.")] == []


@pytest.mark.parametrize("closed", [1, 2], ids=["stdout-closed", "stderr-closed"])
def test_a_command_started_without_stdout_or_stderr(ws, closed):
    # before: stdout closed (cron's '>&-'): AttributeError 'NoneType' object has no
    # attribute 'flush' and a traceback, exit 1, no report; stderr closed: exit 1, no report
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH",
                                                                               ""),
               MPLBACKEND="Agg")
    keep = 2 if closed == 1 else 1
    proc = subprocess.run([sys.executable, "-m", "freqid_casadi", "fit", "plant.csv",
                           "--sections", "1", "--out", "r", "--progress"], cwd=ws, env=env,
                          stdout=subprocess.PIPE if keep == 1 else None,
                          stderr=subprocess.PIPE if keep == 2 else None,
                          preexec_fn=lambda: os.close(closed), timeout=300)
    assert proc.returncode == 0
    said = (proc.stdout if keep == 1 else proc.stderr).decode()
    assert "Traceback" not in said and "error:" not in said
    assert (ws / "r" / "summary.md").is_file() and (ws / "r" / "model.json").is_file()


def test_ipopt_options_are_checked_without_sys_stdout(monkeypatch):
    # before: AttributeError 'NoneType' object has no attribute 'flush' (sys.stdout is None
    # under pythonw or a daemon)
    from freqid_casadi.options import IpoptOptions

    monkeypatch.setattr(sys, "stdout", None)
    opts = IpoptOptions(ipopt={"acceptable_iter": 7})
    assert opts.ipopt_dict() == {"acceptable_iter": 7}


def test_force_keeps_a_users_csv_or_text_beside_a_copied_report(tmp_path, monkeypatch):
    # an unmarked folder holding a copied report and the user's own data or notes is not
    # a report of ours: --force must refuse it and name the foreign file
    from freqid_casadi.report.outputs import is_package_folder, foreign_entry

    for name, text in (("my_measurement.csv", "f,re,im\n1,2,3\n"), ("notes.txt", "mine")):
        folder = tmp_path / name.split(".")[0]
        folder.mkdir()
        (folder / "summary.md").write_text("<!-- generated by: freqid fit x -->\n")
        (folder / "rel_error.csv").write_text("omega,rel\n")
        (folder / name).write_text(text)
        assert foreign_entry(folder) == name
        assert not is_package_folder(folder)
    legacy = tmp_path / "legacy"
    legacy.mkdir()
    (legacy / "summary.md").write_text("<!-- generated by: freqid fit x -->\n")
    (legacy / "rel_error.csv").write_text("omega,rel\n")
    (legacy / "bode.png").write_bytes(b"\x89PNG")
    assert is_package_folder(legacy)


def test_closed_stdout_pipe_is_quiet_and_exits_141(tmp_path):
    # `freqid fit ... | head -c 0` wrote the report, then "error: Broken pipe", exit 2
    import subprocess
    import sys

    from freqid_casadi.cli.common import os_exit

    assert os_exit(FileNotFoundError(2, "No such file or directory", "x.csv")) == 2
    w = np.logspace(-1, 2, 40)
    g = 1.0 / (1 + 0.1j * w)
    np.savetxt(tmp_path / "p.csv", np.column_stack([w, g.real, g.imag]), delimiter=",",
               header="omega,re,im", comments="")
    cmd = (f"{sys.executable} -m freqid_casadi fit p.csv --sections 1 --no-delay "
           "--out rep | head -c 0; echo ${PIPESTATUS[0]}")
    out = subprocess.run(["bash", "-c", cmd], cwd=tmp_path, capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": os.getcwd()})
    assert out.stdout.strip() == "141" and "Broken pipe" not in out.stderr
    assert (tmp_path / "rep" / "summary.md").is_file()

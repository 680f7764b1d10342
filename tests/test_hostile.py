"""Hostile-input matrix: careless and hostile inputs never lose a user's file,
never hang, never print a traceback and never return garbage silently.

Every case is independent and time-bounded (subprocesses have timeouts; in-process cases are
small), and asserts the exit status or the exception, the message, and that no file outside
the intended output was created, changed or deleted (a snapshot of the test's folder tree
before and after). Families:

- output: ``--force`` and ``--out`` safety of every command, the marker file, atomic folders
- batch: unique listed model names, symlinks, FIFOs, hostile file names, a failing file
- interrupt: Ctrl-C and SIGTERM during a fit (IPOPT and barrier-LM) and while writing
- model: the model-file schema, nesting, size and file-type limits
- bounded: order ranges, option validation, extreme frequencies of the uncertainty weight
- messages: one ``error:`` line, warnings only after success, Markdown/CSV escaping
- stability: undamped modes (poles on the imaginary axis) and the meaning of is_stable
- readers: hostile data files
- finite: extreme scales

Run ``pytest tests/test_hostile.py --collect-only -q`` for the case count per family (the
test names start with the family's subject).
"""

import csv
import dataclasses
import hashlib
import io
import json
import os
import re
import selectors
import signal
import stat
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

import freqid_casadi as fc  # noqa: E402
from freqid_casadi import _interrupt  # noqa: E402
from freqid_casadi import _textio as _io  # noqa: E402
from freqid_casadi.report import outputs as _outputs  # noqa: E402
from freqid_casadi.cli import app as cli  # noqa: E402
from freqid_casadi.cli import batch as cli_batch  # noqa: E402
from freqid_casadi.report import folder as report  # noqa: E402
from freqid_casadi.core.data import FrequencyData  # noqa: E402
from freqid_casadi.io.loaders import save_csv  # noqa: E402
from freqid_casadi.errors import DataError, FreqidError, OptionError, StructureError  # noqa: E402
from freqid_casadi.core.model import RationalDelayModel, Structure  # noqa: E402
from freqid_casadi.core.realize import quad_roots as _quad_roots  # noqa: E402
from conftest import one_section_model  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MARKER = _outputs.MARKER

# a small known plant: one lightly damped section, delay 0.01 s, 40 points, 0.1..100 rad/s
_OMEGA = np.logspace(-1, 2, 40)
_MODEL = one_section_model()


def _plant(omega=_OMEGA, name="plant"):
    return FrequencyData(omega, _MODEL.frequency_response(omega), name)


# ----------------------------------------------------------------------------- helpers


def snapshot(root):
    """{relative path: (kind, size, mtime_ns, digest)} of every entry under ``root``."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            p = os.path.join(dirpath, name)
            st = os.lstat(p)
            rel = os.path.relpath(p, root)
            if stat.S_ISREG(st.st_mode):
                with open(p, "rb") as fh:
                    digest = hashlib.sha1(fh.read()).hexdigest()
                out[rel] = ("file", st.st_size, st.st_mtime_ns, digest)
            elif stat.S_ISLNK(st.st_mode):
                out[rel] = ("link", os.readlink(p), None, None)
            elif stat.S_ISDIR(st.st_mode):
                out[rel] = ("dir", None, None, None)
            else:
                out[rel] = ("other", stat.S_IFMT(st.st_mode), None, None)
    return out


def changes(before, after):
    return sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))


def assert_untouched_except(root, before, *allowed):
    """Nothing under ``root`` changed except paths equal to or inside ``allowed``."""
    after = snapshot(root)
    bad = [c for c in changes(before, after)
           if not any(c == a or c.startswith(a.rstrip("/") + os.sep) for a in allowed)]
    assert bad == [], f"unexpected changes: {bad}"
    tmp = [k for k in after if ".tmp-" in k or ".old-" in k]
    assert tmp == [], f"temporary folders left: {tmp}"
    return after


def run_cli(capsys, *argv):
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_error(err, *needles):
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err and "warning" not in err.lower()
    for n in needles:
        assert n in lines[0], (n, lines[0])


def _env():
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env.setdefault("MPLBACKEND", "Agg")
    return env


def run_sub(argv, cwd, timeout=60):
    """``python -m freqid_casadi argv`` in ``cwd`` with a timeout (memory capped at 2 GB)."""
    def limit():                                        # pragma: no cover - in the child
        import resource
        resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))

    return subprocess.run([sys.executable, "-m", "freqid_casadi", *map(str, argv)], cwd=cwd,
                          env=_env(), capture_output=True, text=True, timeout=timeout,
                          preexec_fn=limit)


def write_csv(path, omega, response):
    lines = ["omega,real,imag"] + [f"{float(w)!r},{float(g.real)!r},{float(g.imag)!r}"
                                   for w, g in zip(omega, response)]
    Path(path).write_text("\n".join(lines) + "\n")


def write_records(path, period=16, periods=4):
    """u,y records of a multisine (bins 1..3) through a first-order lag."""
    n = np.arange(period * periods)
    u = sum(np.cos(2 * np.pi * k * n / period + k) for k in (1, 2, 3))
    y = np.zeros_like(u)
    for i in range(1, u.size):
        y[i] = 0.7 * y[i - 1] + 0.3 * u[i - 1]
    Path(path).write_text("u,y\n" + "".join(f"{float(a)!r},{float(b)!r}\n"
                                             for a, b in zip(u, y)))


@pytest.fixture
def ws(tmp_path, monkeypatch):
    """A workspace (the cwd): data/plant.csv, data/notes.txt, rec.csv, marked/ (a folder
    freqid wrote), unmarked/, legacy/ (a report from before the marker), afile.txt and
    link_dir -> marked."""
    root = tmp_path / "ws"
    (root / "data").mkdir(parents=True)
    save_csv(_plant(), root / "data" / "plant.csv")
    (root / "data" / "notes.txt").write_text("precious")
    write_records(root / "rec.csv")
    for name in ("marked", "unmarked", "legacy"):
        (root / name).mkdir()
        (root / name / "old.json").write_text("{}")
    (root / "marked" / MARKER).write_text("")
    (root / "legacy" / "summary.md").write_text("<!-- generated by: freqid fit x -->\n")
    (root / "afile.txt").write_text("a file")
    os.symlink(root / "marked", root / "link_dir")
    os.symlink(root / "rec.csv", root / "reclink.csv")
    monkeypatch.chdir(root)
    return root


@pytest.fixture
def no_figures(monkeypatch):
    """Report figures are not the subject here: skip drawing them (keeps cases fast)."""
    monkeypatch.setattr(report, "_write_figures", lambda *a, **k: None, raising=False)


# ----------------------------------------------------------------------------- output

FIT = ("fit", "data/plant.csv", "--sections", "1")
REFUSED = [
    pytest.param([*FIT, "--out", "", "--force"], "is empty", id="fit-empty-out"),
    pytest.param([*FIT, "--out", "   ", "--force"], "is empty", id="fit-blank-out"),
    pytest.param([*FIT, "--out", ".", "--force"], "current folder", id="fit-cwd"),
    pytest.param([*FIT, "--out", "..", "--force"], "parent of the current folder",
                 id="fit-parent"),
    pytest.param([*FIT, "--out", "/", "--force"], "parent of the current folder",
                 id="fit-root"),
    pytest.param([*FIT, "--out", "{ws}", "--force"], "current folder", id="fit-cwd-abs"),
    pytest.param([*FIT, "--out", "data/..", "--force"], "current folder", id="fit-cwd-dots"),
    pytest.param([*FIT, "--out", "data", "--force"], "holds the input", id="fit-input-folder"),
    pytest.param([*FIT, "--out", "data/", "--force"], "holds the input",
                 id="fit-input-folder-slash"),
    pytest.param([*FIT, "--out", "data/plant.csv", "--force"], "is an input",
                 id="fit-onto-input"),
    pytest.param([*FIT, "--out", "unmarked", "--force"], "not written by freqid",
                 id="fit-unmarked"),
    pytest.param([*FIT, "--out", "marked"], "exists; pass --force", id="fit-no-force"),
    pytest.param([*FIT, "--out", "legacy"], "exists; pass --force", id="fit-legacy-no-force"),
    pytest.param([*FIT, "--out", "afile.txt", "--force"], "not a folder", id="fit-onto-file"),
    pytest.param([*FIT, "--out", "link_dir", "--force"], "not a folder", id="fit-onto-link"),
    pytest.param([*FIT, "--out", "nope/rep"], "parent folder", id="fit-missing-parent"),
    pytest.param(["sweep", "data/plant.csv", "--orders", "2", "--out", "data", "--force"],
                 "holds the input", id="sweep-input-folder"),
    pytest.param(["sweep", "data/plant.csv", "--orders", "2", "--out", "", "--force"],
                 "is empty", id="sweep-empty-out"),
    pytest.param(["example", "B", "--out", ".", "--force"], "current folder", id="example-cwd"),
    pytest.param(["example", "B", "--out", " ", "--force"], "is empty", id="example-blank"),
    pytest.param(["batch", "data", "--sections", "1", "--out", "data", "--force"],
                 "is an input", id="batch-onto-input-folder"),
    pytest.param(["batch", "data", "--sections", "1", "--out", ".", "--force"],
                 "current folder", id="batch-cwd"),
    pytest.param(["batch", "data", "--sections", "1", "--out", "", "--force"], "is empty",
                 id="batch-empty-out"),
    pytest.param(["batch", "data", "--sections", "1", "--out", "unmarked", "--force"],
                 "not written by freqid", id="batch-unmarked"),
    pytest.param(["frf", "rec.csv", "--period", "16", "--out", "rec.csv", "--force"],
                 "is an input", id="frf-onto-records"),
    pytest.param(["frf", "rec.csv", "--period", "16", "--out", "./rec.csv", "--force"],
                 "is an input", id="frf-onto-records-dot"),
    pytest.param(["frf", "rec.csv", "--period", "16", "--out", "reclink.csv", "--force"],
                 "is an input", id="frf-onto-records-link"),
    pytest.param(["frf", "rec.csv", "--period", "16", "--out", ""], "is empty",
                 id="frf-empty-out"),
    pytest.param(["frf", "rec.csv", "--period", "16", "--out", "data", "--force"],
                 "is a folder", id="frf-onto-folder"),
    pytest.param(["reproduce", "--quick", "--out", ".", "--force"], "current folder",
                 id="reproduce-cwd"),
    pytest.param(["ablation", "--quick", "--out", "", "--force"], "is empty",
                 id="ablation-empty-out"),
]


@pytest.mark.parametrize("argv, needle", REFUSED)
def test_output_refused(ws, capsys, argv, needle):
    before = snapshot(ws.parent)
    argv = [a.replace("{ws}", str(ws)) for a in argv]
    code, out, err = run_cli(capsys, *argv)
    assert code == 2
    assert_one_error(err, needle)
    assert_untouched_except(ws.parent, before)


@pytest.mark.parametrize("target", ["marked", "legacy", "new"])
def test_fit_report_replaces_only_package_folders(ws, capsys, no_figures, target):
    before = snapshot(ws.parent)
    code, out, err = run_cli(capsys, *FIT, "--out", target, "--force", "--quiet")
    assert code == 0, err
    after = assert_untouched_except(ws.parent, before, os.path.join("ws", target))
    names = sorted(os.listdir(ws / target))
    assert MARKER in names and "summary.md" in names and "old.json" not in names
    assert (ws / target / MARKER).read_text().startswith("This folder was written by")
    assert "ws/data/plant.csv" in after


def test_force_may_replace_an_empty_folder(ws, capsys, no_figures):
    (ws / "empty").mkdir()
    before = snapshot(ws.parent)
    code, out, err = run_cli(capsys, *FIT, "--out", "empty", "--force", "--quiet")
    assert code == 0, err
    assert_untouched_except(ws.parent, before, "ws/empty")
    assert MARKER in os.listdir(ws / "empty")


def test_too_long_out_name_is_one_error_line(ws, capsys):
    before = snapshot(ws.parent)
    code, out, err = run_cli(capsys, *FIT, "--out", "x" * 300)
    assert code == 2
    assert_one_error(err, "too long")
    assert_untouched_except(ws.parent, before)


def test_undecodable_file_name(ws, capsys):
    name = os.fsdecode(b"\xff.csv")
    save_csv(_plant(), ws / "data" / name)
    before = snapshot(ws.parent)
    code, out, err = run_cli(capsys, "fit", f"data/{name}", "--sections", "1", "--out", "r",
                             "--quiet")
    assert code == 0, err
    assert_untouched_except(ws.parent, before, "ws/r")
    assert "\\udcff" in (ws / "r" / "summary.md").read_text()


def test_frf_force_replaces_its_own_output_only(ws, capsys):
    before = snapshot(ws.parent)
    code, out, err = run_cli(capsys, "frf", "rec.csv", "--period", "16", "--out", "frf.csv")
    assert code == 0, err
    code, out, err = run_cli(capsys, "frf", "rec.csv", "--period", "16", "--out", "frf.csv")
    assert code == 2
    assert_one_error(err, "exists; pass --force")
    code, out, err = run_cli(capsys, "frf", "rec.csv", "--period", "16", "--out", "frf.csv",
                             "--force")
    assert code == 0, err
    assert_untouched_except(ws.parent, before, "ws/frf.csv", "ws/frf.stats.csv")


def test_nul_in_out_dir_is_an_option_error(tmp_path):
    with pytest.raises(OptionError, match="NUL"):
        report.check_out_dir(str(tmp_path / "a\0b"), force=True)


def test_registered_inputs_protect_a_marked_folder(ws):
    (ws / "data" / MARKER).write_text("")        # even a folder freqid wrote
    before = snapshot(ws.parent)
    with _outputs.inputs([ws / "data" / "plant.csv"]):
        with pytest.raises(OptionError, match="holds the input"):
            report.check_out_dir(ws / "data", force=True)
    assert report.check_out_dir(ws / "data", force=True) == str(ws / "data")   # unprotected
    assert_untouched_except(ws.parent, before)


def test_package_folder_recognition(ws):
    assert _outputs.is_package_folder(ws / "marked")
    assert _outputs.is_package_folder(ws / "legacy")
    assert not _outputs.is_package_folder(ws / "unmarked")
    assert not _outputs.is_package_folder(ws / "data")


def test_building_removes_its_temporary_folder_on_error(ws):
    before = snapshot(ws.parent)
    with pytest.raises(ZeroDivisionError):
        with _outputs.building(ws / "new") as (tmp, path):
            assert os.path.isfile(os.path.join(tmp, MARKER))
            Path(tmp, "half.txt").write_text("half")
            1 / 0
    assert_untouched_except(ws.parent, before)


def test_building_removes_its_temporary_folder_on_sigterm(ws):
    before = snapshot(ws.parent)
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    with pytest.raises(KeyboardInterrupt):
        with _outputs.building(ws / "marked", force=True) as (tmp, path):
            Path(tmp, "half.txt").write_text("half")
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)                               # the handler raises before this ends
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    assert_untouched_except(ws.parent, before)


# ----------------------------------------------------------------------------- batch


@pytest.fixture
def bws(tmp_path, monkeypatch):
    """Batch workspace: the cwd holds in/ (data files) and outside.csv."""
    (tmp_path / "in").mkdir()
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _summary_rows(folder):
    with open(folder / "summary.csv", newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def _npz(path, data):
    with open(path, "wb") as fh:
        np.savez(fh, omega=data.omega, response=data.response)


def test_batch_colliding_names_give_distinct_listed_models(bws, capsys):
    save_csv(_plant(), bws / "in" / "a.csv")
    _npz(bws / "in" / "a.npz", _plant())
    _npz(bws / "in" / "a.csv.npz", _plant())
    before = snapshot(bws)
    code, out, err = run_cli(capsys, "batch", "in", "--sections", "1", "--out", "rep")
    assert code in (0, 1), err
    assert_untouched_except(bws, before, "rep")
    rows = _summary_rows(bws / "rep")
    assert [r["file"] for r in rows] == ["a.csv", "a.csv.npz", "a.npz"]
    models = [r["model"] for r in rows]
    assert len(set(models)) == 3 and all(m.startswith("models/") for m in models)
    assert sorted(os.listdir(bws / "rep" / "models")) == sorted(m[7:] for m in models)
    assert MARKER in os.listdir(bws / "rep")
    md = (bws / "rep" / "summary.md").read_text()
    assert all(m in md for m in models)


@pytest.mark.parametrize("paths, expected", [
    pytest.param(["d/A.csv", "d/a.csv"], ["A.csv", "a.csv-2"], id="case-insensitive"),
    pytest.param(["d/.csv"], ["data.csv"], id="dot-name"),
    pytest.param(["d/x.csv", "d/x.npz", "d/y.csv"], ["x.csv", "x.npz", "y"], id="stems"),
])
def test_batch_unique_names(paths, expected):
    assert cli_batch._unique_names(paths) == expected


def test_batch_skips_a_symlink_that_leaves_the_folder(bws, capsys):
    save_csv(_plant(), bws / "in" / "good.csv")
    (bws / "secret.csv").write_text("TOP-SECRET-LINE\n1,2,3\n")
    os.symlink(bws / "secret.csv", bws / "in" / "leak.csv")
    os.symlink(bws / "in" / "good.csv", bws / "in" / "inner.csv")   # stays inside: read
    before = snapshot(bws)
    code, out, err = run_cli(capsys, "batch", "in", "--sections", "1", "--out", "rep")
    assert code in (0, 1), err
    assert_untouched_except(bws, before, "rep")
    text = "".join(p.read_text() for p in (bws / "rep").glob("summary.*"))
    assert "TOP-SECRET" not in text and "leak.csv" not in text and "inner.csv" in text
    assert "warning: skipped 'leak.csv'" in err and not err.startswith("error")


def test_batch_skips_a_fifo(bws):
    save_csv(_plant(), bws / "in" / "good.csv")
    os.mkfifo(bws / "in" / "pipe.csv")
    assert [os.path.basename(p) for p in cli_batch.data_files(bws / "in")] == ["good.csv"]


@pytest.mark.parametrize("name", [
    pytest.param("evil\nname|x.csv", id="newline-pipe"),
    pytest.param("a\r\n# injected.csv", id="crlf-heading"),
    pytest.param("x\u2028<!-- hide.csv", id="line-separator-comment"),
    pytest.param('q,"uote.csv', id="comma-quote"),
])
def test_batch_hostile_file_names_stay_in_their_cell(bws, capsys, name):
    save_csv(_plant(), bws / "in" / name)
    before = snapshot(bws)
    code, out, err = run_cli(capsys, "batch", "in", "--sections", "1", "--out", "rep")
    assert code in (0, 1), err
    assert_untouched_except(bws, before, "rep")
    md = (bws / "rep" / "summary.md").read_text().splitlines()
    table = [line for line in md if line.startswith("|")]
    assert len(table) == 3                               # header, separator, one row
    assert not any(line.startswith("#") for line in md[1:] if line != "# Batch fit")
    assert "<!--" not in "\n".join(md[1:])
    rows = _summary_rows(bws / "rep")
    assert [r["file"] for r in rows] == [name]
    assert len(out.splitlines()) == 2                    # one line per file + the total


def test_batch_goes_on_past_an_extreme_file(bws, capsys):
    save_csv(_plant(), bws / "in" / "good.csv")
    w = np.logspace(300, 301, 40)
    write_csv(bws / "in" / "extreme.csv", w, _MODEL.frequency_response(_OMEGA))
    before = snapshot(bws)
    code, out, err = run_cli(capsys, "batch", "in", "--sections", "1", "--out", "rep")
    assert code in (0, 1), err
    assert_untouched_except(bws, before, "rep")
    rows = {r["file"]: r for r in _summary_rows(bws / "rep")}
    assert set(rows) == {"good.csv", "extreme.csv"}
    assert rows["good.csv"]["model"] == "models/good.json"
    bad = rows["extreme.csv"]
    assert bad["status"] != "failed" or bad["error"]      # failed only with a message
    if bad["status"] != "failed":
        assert np.isfinite(float(bad["max_rel_error"]))


# ----------------------------------------------------------------------------- interrupt


def _long_fit_file(folder):
    data = fc.systems.G_A()
    save_csv(data, folder / "beam.csv")


def _signal_mid_fit(folder, sig, method="ipopt"):
    """Start a long fit, wait for its second stage, send ``sig``; return (rc, stderr, dt).
    The thesis's loop (``--start sequential``): with the default start the rational start
    explains exact data at once and the fit has no second stage."""
    _long_fit_file(folder)
    argv = [sys.executable, "-m", "freqid_casadi", "fit", "beam.csv", "--sections", "17",
            "--integrator", "--method", method, "--start", "sequential", "--progress",
            "--out", "rep"]
    p = subprocess.Popen(argv, cwd=folder, env=_env(), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    sel = selectors.DefaultSelector()
    sel.register(p.stderr, selectors.EVENT_READ)
    err, deadline = [], time.monotonic() + 90
    try:
        while time.monotonic() < deadline:
            if not sel.select(timeout=1):
                continue
            line = p.stderr.readline()
            if not line:
                break
            err.append(line)
            if re.match(r"stage\s+2:", line):
                break
        assert any(re.match(r"stage\s+2:", x) for x in err), "".join(err)
        t0 = time.monotonic()
        p.send_signal(sig)
        out, rest = p.communicate(timeout=30)
        return p.returncode, "".join(err) + rest, time.monotonic() - t0
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()


@pytest.mark.parametrize("sig, method, status", [
    pytest.param(signal.SIGINT, "ipopt", 130, id="sigint-ipopt"),
    pytest.param(signal.SIGTERM, "ipopt", 143, id="sigterm-ipopt"),
    pytest.param(signal.SIGINT, "barrier-lm", 130, id="sigint-barrier-lm"),
])
def test_signal_stops_a_fit(tmp_path, sig, method, status):
    rc, err, dt = _signal_mid_fit(tmp_path, sig, method)
    assert rc == status, err
    assert err.rstrip().splitlines()[-1] == "error: interrupted"
    assert "Traceback" not in err
    assert dt < 20                                        # prompt (noisy shared machine)
    assert sorted(os.listdir(tmp_path)) == ["beam.csv"]   # no report, no temporary folder


def test_sigterm_while_writing_keeps_the_old_report(ws, capsys, monkeypatch, no_figures):
    def killed(*a, **k):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)

    monkeypatch.setattr(report, "render_fit_summary", killed)
    before = snapshot(ws.parent)
    code, out, err = run_cli(capsys, *FIT, "--out", "marked", "--force", "--quiet")
    assert code == 143
    assert_one_error(err, "interrupted")
    assert_untouched_except(ws.parent, before)
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL


@pytest.fixture
def python_sigint():
    """Python's own SIGINT handler for the test: a runner started in the background by a
    non-interactive shell inherits SIGINT ignored (SIG_IGN), where Ctrl-C never arrives."""
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, old)


def test_ctrl_c_stops_an_api_fit_between_ipopt_iterations(python_sigint):
    data = fc.systems.G_C()            # a long fit (27 sections): the signal comes mid-fit
    main = threading.main_thread().ident
    sent = []

    def interrupt():
        sent.append(time.monotonic())
        signal.pthread_kill(main, signal.SIGINT)

    timer = threading.Timer(1.0, interrupt)
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            fc.fit(data, n_sections=27, integrator=True)
    finally:
        timer.cancel()
    assert sent and time.monotonic() - sent[0] < 10
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert not _interrupt.requested()


def test_guard_defers_the_signal_and_clears_it(python_sigint):
    with pytest.raises(_interrupt.Interrupted) as info:
        with _interrupt.guard():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
            assert _interrupt.requested()                   # deferred inside the solver
    assert info.value.signum == signal.SIGINT and _interrupt.exit_status(info.value) == 130
    assert not _interrupt.requested()


def test_ipopt_iteration_callback_reports_the_flag():
    import casadi as ca

    x = ca.MX.sym("x", 2)
    cb = _interrupt.ipopt_callback({"x": x, "f": ca.sumsqr(x)})["iteration_callback"]
    args = [np.zeros(2), 0.0, np.zeros(0), np.zeros(2), np.zeros(0), np.zeros(0)]
    assert float(cb(*args)) == 0.0
    _interrupt._STATE["signum"] = signal.SIGINT
    try:
        assert float(cb(*args)) == 1.0
    finally:
        _interrupt._STATE["signum"] = None


# ----------------------------------------------------------------------------- model


def _with(path, value):
    def make():
        d = _MODEL.to_dict()
        target = d
        for k in path[:-1]:
            target = target[k]
        target[path[-1]] = value
        return json.dumps(d)
    return make


def _beta_with(**idx):
    def make():
        d = _MODEL.to_dict()
        for k, v in idx.items():
            d["beta"][int(k[1:])] = v
        return json.dumps(d)
    return make


MODEL_TEXTS = [
    pytest.param(_with(("structure", "integrator"), "false"),
                 "must be true, false or an integer k", id="integrator-str"),
    pytest.param(_with(("structure", "delay"), 1), "JSON boolean", id="delay-int"),
    pytest.param(_with(("version",), 2), "version 2 is not supported", id="version-2"),
    pytest.param(_with(("version",), "1"), "'version' must be an integer", id="version-str"),
    pytest.param(lambda: json.dumps({k: v for k, v in _MODEL.to_dict().items()
                                     if k != "version"}), "missing field 'version'",
                 id="version-missing"),
    pytest.param(_beta_with(b2=0.0, b4=0.0), "all-zero numerator", id="zero-numerator"),
    pytest.param(_beta_with(b5=0.0, b7=0.0), "all-zero denominator", id="zero-denominator"),
    pytest.param(_beta_with(b2=0.0, b4=0.0, b5=0.0, b7=0.0), "all-zero", id="zero-over-zero"),
    pytest.param(lambda: _MODEL.to_json().replace("2.0", "NaN", 1), "NaN", id="nan-literal"),
    pytest.param(lambda: _MODEL.to_json().replace("2.0", "Infinity", 1), "Infinity",
                 id="infinity-literal"),
    pytest.param(lambda: _MODEL.to_json().replace("2.0", "1e400", 1), "finite",
                 id="overflowing-number"),
    pytest.param(_beta_with(b1=-2.0), "finite and >= 0", id="negative-gain"),
    pytest.param(_beta_with(b3=True), "must be a number", id="bool-in-beta"),
    pytest.param(_beta_with(b3="0.3"), "must be a number", id="string-in-beta"),
    pytest.param(_with(("beta",), [0.0, 1.0]), "beta has 2 entries", id="short-beta"),
    pytest.param(_with(("beta",), 3.0), "'beta' must be a list", id="beta-scalar"),
    pytest.param(_with(("extra",), 1), "unknown field", id="unknown-field"),
    pytest.param(_with(("structure", "colour"), "red"), "unknown structure field",
                 id="unknown-structure-field"),
    pytest.param(_with(("structure", "n_sections"), -1), "n_sections must be >= 0",
                 id="negative-sections"),
    pytest.param(_with(("structure", "n_sections"), 1.5), "must be an integer",
                 id="fractional-sections"),
    pytest.param(_with(("structure", "basis"), "third-order"), "basis", id="unknown-basis"),
    pytest.param(_with(("param_names",), ["x"] * 8), "param_names", id="param-names"),
    pytest.param(_with(("format",), "other"), "not a freqid_casadi model", id="format"),
    pytest.param(lambda: "[" * 200_000 + "]" * 200_000, "nests", id="deep-nesting"),
    pytest.param(lambda: '{"format": "' + "[" * 100 + '"}', "not a freqid_casadi model",
                 id="brackets-in-a-string-are-not-nesting"),
    pytest.param(lambda: "[1, 2]", "must be an object", id="top-level-list"),
    pytest.param(_with(("version",), 10 ** 5000 // 10 ** 4990), "version", id="big-version"),
    pytest.param(lambda: _MODEL.to_json().replace('"version": 1', '"version": ' + "1" * 5000),
                 "not valid JSON", id="5000-digit-integer"),
    pytest.param(_with(("structure", "n_sections"), 10 ** 18), "beta has 8 entries",
                 id="huge-n-sections"),
]


@pytest.mark.parametrize("make, needle", MODEL_TEXTS)
def test_model_schema(tmp_path, make, needle):
    path = tmp_path / "model.json"
    path.write_text(make(), encoding="utf-8")
    before = snapshot(tmp_path)
    with pytest.raises(DataError) as info:
        RationalDelayModel.load(path)
    assert needle in str(info.value) and str(path) in str(info.value)
    assert_untouched_except(tmp_path, before)


@pytest.mark.parametrize("idx, needle", [((2, 4), "section 1 has an all-zero numerator"),
                                         ((5, 7), "section 1 has an all-zero denominator")])
def test_a_model_built_with_an_all_zero_factor_is_refused(idx, needle):
    # the JSON loader refused it, the constructor took it (a model 0 or inf everywhere)
    beta = np.array(_MODEL.beta)
    beta[list(idx)] = 0.0
    with pytest.raises(StructureError, match=needle):
        RationalDelayModel(_MODEL.structure, beta)


def test_model_with_a_bom_loads(tmp_path):
    (tmp_path / "m.json").write_bytes(b"\xef\xbb\xbf" + _MODEL.to_json().encode())
    assert RationalDelayModel.load(tmp_path / "m.json") == _MODEL


def test_model_round_trip_still_bit_identical(tmp_path):
    for m in (_MODEL, RationalDelayModel(Structure(2, integrator=True, basis="first-order"),
                                         [0.0, 1 / 3, 1e-300, 1e300, 0.0, 5.0, 1.0, 0.0,
                                          2.0, 7.0])):
        m.save(tmp_path / "m.json")
        back = RationalDelayModel.load(tmp_path / "m.json")
        assert back == m and back.beta.tobytes() == m.beta.tobytes()


@pytest.mark.parametrize("kind", ["fifo", "dev-zero", "folder", "huge", "binary"])
def test_model_file_kinds(tmp_path, kind):
    path = tmp_path / "m.json"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "dev-zero":
        path = Path("/dev/zero")
    elif kind == "folder":
        path.mkdir()
    elif kind == "huge":
        with open(path, "wb") as fh:
            fh.truncate(64 * 2**20)                       # sparse: 64 MB of zeros
    else:
        path.write_bytes(b"\xff\xfe\x00\x01garbage")
    t0 = time.monotonic()
    with pytest.raises(DataError) as info:
        RationalDelayModel.load(path)
    assert time.monotonic() - t0 < 5
    needle = {"fifo": "not a regular file", "dev-zero": "not a regular file",
              "folder": "not a regular file", "huge": "more than the limit",
              "binary": "not UTF-8"}[kind]
    assert needle in str(info.value)


# ----------------------------------------------------------------------------- bounded


def test_sweep_huge_order_range_is_refused_at_once(ws, capsys):
    before = snapshot(ws.parent)
    t0 = time.monotonic()
    code, out, err = run_cli(capsys, "sweep", "data/plant.csv", "--orders", "2:2000000000:2",
                             "--out", "sw")
    assert time.monotonic() - t0 < 5
    assert code == 2
    assert_one_error(err, "1000000000 orders to fit", "more than 200")
    assert_untouched_except(ws.parent, before)


@pytest.mark.parametrize("spec", ["1_0", "\u0661\u0660", "0:4", "4:2", "", "2:4:0", "a",
                                  "2:999999999999999:2", "2,,4", "-2", "2:4:2:2"])
def test_parse_orders_rejects(spec):
    from freqid_casadi.fitting.sweep import parse_orders

    with pytest.raises(OptionError, match="orders"):
        parse_orders(spec)


def test_sweep_api_counts_a_range_before_listing_it():
    from freqid_casadi.fitting.sweep import sweep

    with pytest.raises(OptionError, match="orders to fit"):
        sweep(_plant(), range(2, 2 * 10**12, 2))


@pytest.mark.parametrize("argv, needle", [
    pytest.param([*FIT[:3], "1_0", "--out", "r"], "--sections", id="sections-underscore"),
    pytest.param([*FIT[:3], "\u0663", "--out", "r"], "--sections", id="sections-arabic"),
    pytest.param([*FIT[:3], "0", "--out", "r"], "--sections", id="sections-zero"),
    pytest.param([*FIT, "--tol", "1_0", "--out", "r"], "--tol", id="tol-underscore"),
    pytest.param([*FIT, "--tol", "nan", "--out", "r"], "--tol", id="tol-nan"),
    pytest.param([*FIT, "--tol", "1e999", "--out", "r"], "--tol", id="tol-inf"),
    pytest.param([*FIT, "--min-damping", "\u0660.5", "--out", "r"], "--min-damping",
                 id="damping-arabic"),
    pytest.param([*FIT, "--min-damping", "1", "--out", "r"], "--min-damping",
                 id="damping-one"),
    pytest.param(["batch", "data", "--sections", "1", "--jobs", "0", "--out", "r"], "--jobs",
                 id="jobs-zero"),
    pytest.param([*FIT, "--method", "newton", "--out", "r"], "--method", id="method-unknown"),
    pytest.param([*FIT[:3], "99999999999999999999", "--out", "r"], "too few data points",
                 id="sections-huge"),
    pytest.param(["example", "B", "--sections", "1000000", "--out", "r"], "too few data points",
                 id="example-sections-huge"),
])
def test_cli_numbers_and_choices(ws, capsys, argv, needle):
    before = snapshot(ws.parent)
    code, out, err = run_cli(capsys, *argv)
    assert code == 2
    assert_one_error(err, needle)
    assert_untouched_except(ws.parent, before)


@pytest.mark.parametrize("kwargs, needle", [
    pytest.param(dict(max_iter=-1), "max_iter", id="max-iter-negative"),
    pytest.param(dict(final_max_iter=0), "final_max_iter", id="final-max-iter-zero"),
    pytest.param(dict(ipopt={"foo": 1}), "foo", id="ipopt-unknown-name"),
    pytest.param(dict(ipopt={"tol": "abc"}), "type mismatch", id="ipopt-wrong-type"),
    pytest.param(dict(ipopt={"max_iter": -5}), "max_iter", id="ipopt-out-of-range"),
    pytest.param(dict(ipopt={"hessian_approximation": "bogus"}), "bogus",
                 id="ipopt-bad-choice"),
    pytest.param(dict(ipopt={"linear_solver": "ma27"}), "Invalid_Option",
                 id="ipopt-missing-solver"),
    pytest.param(dict(hessian="newton"), "hessian", id="hessian-unknown"),
])
def test_ipopt_options_are_checked_at_the_entry_point(kwargs, needle, capfd):
    from freqid_casadi.options import IpoptOptions

    with pytest.raises(OptionError) as info:
        IpoptOptions(**kwargs)
    assert needle in str(info.value)
    out, err = capfd.readouterr()
    assert out == "" and err == ""                        # IPOPT's complaint not shown


def test_barrier_lm_options_are_checked():
    from freqid_casadi.options import BarrierLMOptions

    with pytest.raises(OptionError, match="max_iter"):
        BarrierLMOptions(max_iter=-1)


@pytest.mark.parametrize("legacy", [dict(max_iter=-1), dict(ipopt_options={"foo": 1})])
def test_fit_legacy_keywords_name_the_option_object(legacy):
    with pytest.raises(TypeError, match="IpoptOptions"):
        fc.fit(_plant(), n_sections=1, **legacy)


@pytest.mark.parametrize("lo", [200, -201, 300, -301])
def test_uncertainty_weight_at_extreme_frequencies(lo):
    from freqid_casadi.uncertainty.weight import fit_uncertainty_weight

    e = 0.1 + 0.05 * np.sin(np.arange(30))
    ref = fit_uncertainty_weight(np.logspace(0, 1, 30), e, order=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        w = fit_uncertainty_weight(np.logspace(lo, lo + 1, 30), e, order=1)
    assert np.all(np.isfinite(w.magnitude)) and np.all(w.magnitude >= e)
    assert w.objective == pytest.approx(ref.objective, rel=0.05)


def test_uncertainty_weight_band_too_wide():
    from freqid_casadi.uncertainty.weight import fit_uncertainty_weight

    with pytest.raises(DataError, match="600 decades"):
        fit_uncertainty_weight(np.logspace(-300, 300, 30), np.full(30, 0.1))


# ----------------------------------------------------------------------------- messages


def test_no_warning_before_the_error_line(ws, capsys, monkeypatch):
    def noisy(*a, **k):
        warnings.warn("overflow encountered in multiply", RuntimeWarning)
        raise DataError("the fit failed")

    monkeypatch.setattr(cli, "fit", noisy)
    before = snapshot(ws.parent)
    code, out, err = run_cli(capsys, *FIT, "--out", "rep")
    assert code == 2
    assert err == "error: the fit failed\n"
    assert_untouched_except(ws.parent, before)


def test_warnings_follow_a_success_as_warning_lines(ws, capsys, monkeypatch, no_figures):
    real = cli.fit

    def noisy(*a, **k):
        warnings.warn("something odd\non two lines", UserWarning)
        return real(*a, **k)

    monkeypatch.setattr(cli, "fit", noisy)
    before = snapshot(ws.parent)
    code, out, err = run_cli(capsys, *FIT, "--out", "rep", "--quiet")
    assert code == 0
    assert err == "warning: something odd on two lines\n"
    assert "report:" in out
    assert_untouched_except(ws.parent, before, "ws/rep")


def test_unexpected_exception_is_one_line_not_a_traceback(ws, capsys, monkeypatch):
    def broken(*a, **k):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(cli, "fit", broken)
    before = snapshot(ws.parent)
    code, out, err = run_cli(capsys, *FIT, "--out", "rep")
    assert code == 1
    assert_one_error(err, "internal error", "ZeroDivisionError")
    assert_untouched_except(ws.parent, before)


def test_keyboard_interrupt_in_process(ws, capsys, monkeypatch):
    def stop(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "fit", stop)
    before = snapshot(ws.parent)
    code, out, err = run_cli(capsys, *FIT, "--out", "rep")
    assert code == 130 and err == "error: interrupted\n"
    assert_untouched_except(ws.parent, before)


def test_data_name_cannot_inject_markdown(ws, capsys, no_figures):
    name = "x\n# Injected heading\n<!-- |pipe|"
    save_csv(_plant(name=name), ws / "data" / "odd.csv")
    os.rename(ws / "data" / "odd.csv", ws / "data" / f"{name}.csv")
    before = snapshot(ws.parent)
    code, out, err = run_cli(capsys, "fit", f"data/{name}.csv", "--sections", "1", "--out",
                             "rep", "--quiet")
    assert code == 0, err
    assert_untouched_except(ws.parent, before, "ws/rep")
    md = (ws / "rep" / "summary.md").read_text().splitlines()
    assert not any(line.startswith("# Injected") for line in md)
    assert not any("<!--" in line for line in md[1:])    # only the generated-by comment
    assert md[2].startswith("# Fit report: x # Injected heading &lt;!--")


@pytest.mark.parametrize("text, expected", [
    ("a\nb", "a b"), ("a\r\nb", "a b"), ("a\u2028b\u2029c", "a b c"), ("a\x00\x07b", "ab"),
    ("<!-- x -->", "&lt;!-- x -->"), ("  pad  ", "pad"),
])
def test_md_text(text, expected):
    assert _io.md_text(text) == expected


def test_md_cell_and_csv_row():
    assert _io.md_cell("a|b\nc") == "a\\|b c"
    row = _io.csv_row(['a,b', 'q"x', "l1\nl2", None, 1.5])
    assert next(csv.reader(io.StringIO(row))) == ["a,b", 'q"x', "l1\nl2", "", "1.5"]


def test_generated_by_line_stays_one_comment():
    line = report.generated_by_line("freqid fit 'a-->b\n.csv'")
    assert line.count("-->") == 1 and "\n" not in line and line.endswith("-->")


# ----------------------------------------------------------------------------- stability


def _undamped(n_points=400, lo=-1, hi=2, wns=(3.0, 20.0)):
    w = np.logspace(lo, hi, n_points)
    s = 1j * w
    g = np.ones_like(s)
    for wn in wns:
        g = g * wn ** 2 / (s ** 2 + wn ** 2)              # zeta = 0 exactly
    return FrequencyData(w, g, "undamped")


@pytest.mark.parametrize("start", ["rational", "sequential"])
def test_undamped_modes_give_a_stable_model(start):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = fc.fit(_undamped(), n_sections=2, start=start)
    p = r.model.poles()
    assert np.all(p.real <= 0)                            # never in the open RHP
    assert r.model.is_stable() and r.model.is_minimum_phase()
    on_axis = r.model.poles_on_axis()
    assert r.model.is_stable(strict=True) == (on_axis.size == 0)
    assert np.isfinite(r.max_rel_error) and r.max_rel_error < 1e-3


def test_report_counts_poles_on_the_axis(tmp_path, no_figures):
    m = RationalDelayModel(Structure(1), [0.0, 1.0, 1.0, 0.3, 2.0, 1.0, 0.0, 3.0])
    assert m.is_stable() and not m.is_stable(strict=True)
    r = fc.fit(_plant(), n_sections=1)
    r2 = dataclasses.replace(r, model=m)
    s = report.fit_summary(r2, command="x")
    assert s["checks"]["stable"] and s["checks"]["n_poles_on_axis"] == 2
    md = report.render_fit_summary(s)
    assert "| P_N stable | only marginally (" in md and "2 pole(s) on the imaginary axis" in md
    # a zero pair on the axis is said of the minimum phase the same way
    m = RationalDelayModel(Structure(1), [0.0, 1.0, 1.0, 0.0, 2.0, 1.0, 0.3, 3.0])
    s = report.fit_summary(dataclasses.replace(r, model=m), command="x")
    assert s["checks"]["n_zeros_on_axis"] == 2 and s["checks"]["n_poles_on_axis"] == 0
    md = report.render_fit_summary(s)
    assert "| P_N minimum phase | only marginally (" in md
    assert "2 zero(s) on the imaginary axis" in md and "| P_N stable | yes (" in md


@pytest.mark.parametrize("c", [(1.0, 0.0, 9.0), (1.0, 1e-300, 1.0), (2.0, 0.0, 1e-300),
                               (1.0, 1e200, 1.0), (1e-300, 0.0, 1.0), (1.0, 2.0, 0.0),
                               (3.0, 1e-17, 7.0)])
def test_section_roots_never_leave_the_closed_lhp(c):
    roots = _quad_roots(*c)
    assert roots and all(np.isfinite(r.real) and r.real <= 0 for r in roots)
    if c[1] == 0:
        assert all(r.real == 0 for r in roots)


# ----------------------------------------------------------------------------- readers


def _hostile_data(folder, kind):
    """A hostile data file of ``kind`` in ``folder``; returns its name."""
    p = folder / f"{kind}.csv"
    if kind == "fifo":
        os.mkfifo(p)
    elif kind == "bom":
        p.write_bytes(b"\xef\xbb\xbf" + b"".join(
            f"{float(w)!r},{float(g.real)!r},{float(g.imag)!r}\n".encode() for w, g in
            zip(_OMEGA, _MODEL.frequency_response(_OMEGA))).join([b"omega,real,imag\n", b""]))
    elif kind in ("underscore", "arabic"):
        rows = [f"{float(w)!r},{float(g.real)!r},{float(g.imag)!r}" for w, g in
                zip(_OMEGA, _MODEL.frequency_response(_OMEGA))]
        w3 = rows[3].split(",")[0]
        rows[3] = f"{w3},{'1_0' if kind == 'underscore' else chr(0x661)},0"
        p.write_text("omega,real,imag\n" + "\n".join(rows) + "\n")
    elif kind == "huge-cell":
        p.write_text("omega,real,imag\n" + "1" * 200_000 + ",1,0\n2,1,0\n")
    elif kind == "db7000":
        p.write_text("omega,magnitude_db,phase_deg\n1,7000,0\n2,7000,0\n3,7000,0\n")
    else:
        p = folder / f"{kind}.npz"
        if kind == "npz-header":
            import zipfile

            buf = io.BytesIO()
            np.lib.format.write_array_header_1_0(
                buf, {"descr": "<f8", "fortran_order": False, "shape": (10 ** 11,)})
            raw = buf.getvalue() + b"\0" * 64           # claims 800 GB, holds 64 bytes
            with zipfile.ZipFile(p, "w") as z:
                z.writestr("omega.npy", raw)
                z.writestr("response.npy", raw)
        elif kind == "datetime":
            with open(p, "wb") as fh:
                np.savez(fh, omega=np.arange(1, 11).astype("datetime64[D]"),
                         response=np.ones(10, complex))
    return p.name


@pytest.mark.parametrize("kind, loads", [
    pytest.param("fifo", False, id="fifo"),
    pytest.param("bom", True, id="bom"),
    pytest.param("underscore", False, id="1_0"),
    pytest.param("arabic", False, id="non-ascii-digit"),
    pytest.param("huge-cell", False, id="huge-cell"),
    pytest.param("db7000", False, id="7000-dB"),
    pytest.param("npz-header", False, id="npz-header"),
    pytest.param("datetime", False, id="datetime64-omega"),
])
def test_hostile_data_files(tmp_path, kind, loads):
    name = _hostile_data(tmp_path, kind)
    before = snapshot(tmp_path)
    proc = run_sub(["fit", name, "--sections", "1", "--out", "rep", "--quiet"], tmp_path,
                   timeout=10 if kind == "fifo" else 60)
    assert "Traceback" not in proc.stderr and "warning" not in proc.stderr.lower()
    if loads:
        assert proc.returncode == 0, proc.stderr
        assert_untouched_except(tmp_path, before, "rep")
    else:
        assert proc.returncode == 2
        assert_one_error(proc.stderr)
        assert_untouched_except(tmp_path, before)


def test_dev_zero_is_refused(tmp_path):
    proc = run_sub(["fit", "/dev/zero", "--sections", "1", "--out", "rep"], tmp_path, 10)
    assert proc.returncode == 2
    assert_one_error(proc.stderr)
    assert os.listdir(tmp_path) == []


def test_frf_from_periodic_unexcited_bin():
    from freqid_casadi.experiment import frf_from_periodic

    n = np.arange(64)
    u = np.cos(2 * np.pi * n / 16)
    with pytest.raises(DataError):
        frf_from_periodic(u, u, 16, bins=[1, 2])            # bin 2 carries no input


def test_frf_huge_fs_warns_nothing(tmp_path):
    write_records(tmp_path / "rec.csv")
    proc = run_sub(["frf", "rec.csv", "--period", "16", "--fs", "1e308", "--out", "f.csv"],
                   tmp_path, 60)
    assert "warning" not in proc.stderr.lower() and "Traceback" not in proc.stderr
    assert proc.returncode in (0, 2)
    if proc.returncode == 2:
        assert_one_error(proc.stderr)


# ----------------------------------------------------------------------------- finite


@pytest.mark.parametrize("omega_scale, response_scale", [
    pytest.param(1e150, 1.0, id="omega-1e150"),
    pytest.param(1e-150, 1.0, id="omega-1e-150"),
    pytest.param(1.0, 1e-310, id="response-1e-310"),
    pytest.param(1e300, 1.0, id="omega-1e300"),
])
def test_extreme_scales_give_finite_results_or_an_error(omega_scale, response_scale):
    data = FrequencyData(_OMEGA * omega_scale,
                         _MODEL.frequency_response(_OMEGA) * response_scale, "scaled")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = fc.fit(data, n_sections=1)
    except FreqidError:
        return
    assert np.isfinite(r.max_rel_error) and np.isfinite(r.model.gain)
    assert r.max_rel_error < 1e-3                          # the problem is scale-free


def test_ctrl_c_while_a_stage_builds_its_casadi_expressions_is_not_lost(python_sigint,
                                                                         monkeypatch):
    # a KeyboardInterrupt raised inside CasADi's argument conversion (SWIG calls back into
    # Python, e.g. for an MX's shape) is swallowed there: 3 of 25 Ctrl-C's at random times
    # of a fit of C were lost. Signals are now deferred while a stage is built and solved
    # and raised as Interrupted when it returns; here the signal arrives mid-build.
    from freqid_casadi.fitting import stages

    built = []
    real = stages.stage_functions

    def build_then_signal(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)            # during the build
        funcs = real(*args, **kwargs)                  # the build is not interrupted
        built.append(funcs)
        return funcs

    monkeypatch.setattr(stages, "stage_functions", build_then_signal)
    w = np.logspace(-1, 2, 40)
    with pytest.raises(KeyboardInterrupt) as info:
        fc.fit(w, 1 / (1 + 1j * w), n_sections=1, delay=False)
    assert isinstance(info.value, _interrupt.Interrupted) and len(built) == 1
    assert not _interrupt.requested()
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def _signal_during(module, name, monkeypatch):
    """Make ``module.name`` send SIGINT to this process, then do its work; returns the list
    of its results."""
    built, real = [], getattr(module, name)

    def build_then_signal(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)
        out = real(*args, **kwargs)
        built.append(out)
        return out

    monkeypatch.setattr(module, name, build_then_signal)
    return built


def test_ctrl_c_while_a_shared_fit_builds_its_problem_is_not_lost(python_sigint, monkeypatch):
    # the shared fit built its CasADi problems outside any deferral
    from freqid_casadi.modal import shared

    built = _signal_during(shared, "SharedProblem", monkeypatch)
    w = np.logspace(-1, 2, 40)
    datas = [FrequencyData(w, g / (1 + 0.1j * w)) for g in (1.0, 2.0)]
    with pytest.raises(KeyboardInterrupt) as info:
        fc.fit_shared(datas, n_sections=1)
    assert isinstance(info.value, _interrupt.Interrupted) and len(built) == 1
    assert not _interrupt.requested()
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_ctrl_c_while_the_minimax_polish_builds_its_functions_is_not_lost(python_sigint,
                                                                         monkeypatch):
    from freqid_casadi.fitting import mainloop

    built = _signal_during(mainloop, "stage_functions", monkeypatch)
    w = np.logspace(-1, 2, 40)
    with pytest.raises(KeyboardInterrupt) as info:
        fc.fit(w, 1 / (1 + 1j * w), n_sections=1, delay=False, objective="minimax")
    assert isinstance(info.value, _interrupt.Interrupted) and len(built) == 1
    assert not _interrupt.requested()

"""Tests of :mod:`freqid_casadi.fitting.batch` (fit_many) and the ``freqid batch`` command:
per-dataset errors, option errors, results independent of the number of processes and of the
scheduler, atomic output under KeyboardInterrupt."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.report.outputs import MARKER
from freqid_casadi.fitting import batch
from freqid_casadi.cli import app as cli
from freqid_casadi.cli import batch as cli_batch
from freqid_casadi.fitting.batch import BATCH_STATUSES, BatchItem, fit_many
from freqid_casadi.errors import DataError, OptionError, StructureError

OMEGA = np.logspace(-1, 2, 30)
BETAS = [[0.01, 2.0, 1.0, 0.05, 3.0, 1.0, 0.2, 5.0],
         [0.0, 0.5, 1.2, 0.3, 1.0, 0.8, 0.1, 2.0],
         [0.02, 5.0, 0.7, 0.6, 10.0, 1.5, 0.05, 4.0],
         [0.005, 1.0, 1.0, 0.1, 20.0, 1.0, 0.4, 8.0]]
OPTIONS = dict(n_sections=1)

# the same datasets, rebuilt in another interpreter
_SUBPROCESS = f"""
import json, numpy as np, freqid_casadi as fc
from freqid_casadi.fitting.batch import fit_many
w = np.logspace(-1, 2, 30)
data = [fc.FrequencyData(w, fc.RationalDelayModel(fc.Structure(1), b).frequency_response(w),
                         f"d{{k}}") for k, b in enumerate({BETAS!r})]
print(json.dumps([i.result.model.to_json() for i in fit_many(data, n_sections=1)]))
"""


def _datasets():
    return [fc.FrequencyData(OMEGA, fc.RationalDelayModel(fc.Structure(1), b)
                             .frequency_response(OMEGA), f"d{k}")
            for k, b in enumerate(BETAS)]


@pytest.fixture(scope="module")
def serial():
    return fit_many(_datasets(), **OPTIONS)


def _jsons(items):
    return [i.result.model.to_json() for i in items]


def test_serial_items_match_fit(serial):
    assert [i.name for i in serial] == ["d0", "d1", "d2", "d3"]
    for item, data in zip(serial, _datasets()):
        assert isinstance(item, BatchItem) and item.ok and item.error is None
        assert item.status == item.result.status and item.status in BATCH_STATUSES[:3]
        assert isinstance(item.status, fc.FitStatus)
        assert item.result.model.to_json() == fc.fit(data, **OPTIONS).model.to_json()


def test_processes_and_a_fresh_interpreter_give_identical_json(serial):
    """Determinism across processes: joblib workers and a new interpreter reproduce the
    serial model JSON byte for byte."""
    pytest.importorskip("joblib", reason="joblib not installed (needed for jobs > 1)")
    parallel = fit_many(_datasets(), n_jobs=2, **OPTIONS)
    assert _jsons(parallel) == _jsons(serial)
    out = subprocess.run([sys.executable, "-c", _SUBPROCESS], capture_output=True,
                         text=True, check=True, timeout=120).stdout
    assert json.loads(out) == _jsons(serial)


@pytest.mark.parametrize("path", ["fork", "loky"])
def test_both_local_backends_match_serial(serial, monkeypatch, path):
    """Forked workers (Linux, no other thread running) and joblib's loky (elsewhere, or
    when another thread runs) give the serial JSON; the choice is the documented one."""
    import multiprocessing
    import threading

    if path == "fork" and "fork" not in multiprocessing.get_all_start_methods():
        pytest.skip("this platform cannot fork")
    if path == "fork" and threading.active_count() > 1:
        # an earlier test's joblib pool keeps loky's manager thread alive in this process:
        # the package then rightly refuses to fork (the loky case below covers that path)
        pytest.skip("another thread runs in this test process; forking is not safe")
    from freqid_casadi import _workers

    used = []
    for name in ("fork_submit", "_run_joblib"):
        original = getattr(_workers, name)
        monkeypatch.setattr(_workers, name,
                            lambda *a, _o=original, _n=name: used.append(_n) or _o(*a))
    if path == "loky":
        monkeypatch.setattr(threading, "active_count", lambda: 2)   # as with a live thread
    items = fit_many(_datasets(), n_jobs=2, **OPTIONS)
    assert used == ["fork_submit" if path == "fork" else "_run_joblib"]
    assert _jsons(items) == _jsons(serial)


def test_forked_workers_report_a_bad_file_and_go_on(tmp_path, serial):
    bad = tmp_path / "bad.csv"
    bad.write_text("not,a\nfrequency,response\n")
    items = fit_many([bad, *_datasets()], n_jobs=2, **OPTIONS)
    assert items[0].status == "error" and "bad" == items[0].name
    assert _jsons(items[1:]) == _jsons(serial)


def test_dask_local_cluster_matches_serial(serial):
    distributed = pytest.importorskip("distributed",
                                      reason="dask/distributed not installed (extra [dask])")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        items = fit_many(_datasets(), scheduler=cluster.scheduler_address, **OPTIONS)
    assert [i.name for i in items] == [i.name for i in serial]
    assert _jsons(items) == _jsons(serial)
    assert [i.status for i in items] == [i.status for i in serial]


def test_a_failing_dataset_is_reported_not_fatal(tmp_path):
    good = _datasets()[0]
    fc.save_csv(good, tmp_path / "good.csv")
    (tmp_path / "bad.csv").write_text("omega,real,imag\n1,2,x\n")
    few = fc.FrequencyData(OMEGA[:5], good.response[:5], "few")
    items = fit_many([tmp_path / "bad.csv", tmp_path / "good.csv", few, tmp_path / "no.npz"],
                     **OPTIONS)
    assert [i.name for i in items] == ["bad", "good", "few", "no"]
    assert [i.status for i in items] == ["error", items[1].result.status, "error", "error"]
    assert items[1].status in ("ok", "poor-fit", "not-converged")
    assert items[0].error == ("DataError: " + repr(os.fspath(tmp_path / "bad.csv")) +
                              " line 2, column 'imag': 'x' is not a number")
    assert items[0].source == os.fspath(tmp_path / "bad.csv") and items[2].source is None
    assert items[2].error.startswith("DataError: too few data points")
    assert "not found" in items[3].error
    assert items[1].result.max_rel_error < 1e-6


@pytest.mark.parametrize("kwargs, exc, match", [
    (dict(n_sections=1, n_jobs=0), OptionError, "n_jobs must be a positive integer"),
    (dict(n_sections=1, n_jobs=1.5), OptionError, "n_jobs must be a positive integer"),
    (dict(n_sections=1, jobs=2), TypeError, "takes n_jobs=, not jobs="),
    (dict(n_sections=1, progress="bar"), OptionError, "progress must be True, False"),
    (dict(n_sections=1, sections=2), OptionError, "unknown fit option.*'sections'"),
    (dict(), OptionError, "n_sections is missing"),
    (dict(n_sections=1, basis="cubic"), OptionError, "unknown basis 'cubic'"),
    (dict(n_sections=0), StructureError, "n_sections must be >= 1"),
    (dict(n_sections=1, method="newton"), OptionError, "unknown method 'newton'"),
    (dict(n_sections=1, scheduler=42), OptionError, "address string or a distributed"),
])
def test_option_errors_are_raised_once(kwargs, exc, match):
    with pytest.raises(exc, match=match):
        fit_many(_datasets()[:2], **kwargs)


def test_progress_receives_every_item_in_order(capsys):
    seen = []
    items = fit_many(_datasets()[:3], progress=seen.append, **OPTIONS)
    assert seen == items
    fit_many(_datasets()[:2], progress="lines", **OPTIONS)
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 2 and "max rel. error" in lines[0]


def test_bad_dataset_type():
    with pytest.raises(DataError, match=r"datasets\[1\] must be a FrequencyData or a file"):
        fit_many([_datasets()[0], 3.0], n_sections=1)
    assert fit_many([], n_sections=1) == []


def test_missing_dask_is_a_clear_option_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)      # import fails
    with pytest.raises(OptionError, match=r"pip install freqid_casadi\[dask\]"):
        fit_many(_datasets()[:1], scheduler="tcp://127.0.0.1:1", n_sections=1)


# ----------------------------------------------------------------------------- CLI


@pytest.fixture
def batch_cli(monkeypatch):
    monkeypatch.setitem(cli.COMMANDS, "batch", (cli_batch.add_cli, cli_batch.run_cli))


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "data").mkdir()
    for k, d in enumerate(_datasets()[:2]):
        fc.save_csv(d, tmp_path / "data" / f"d{k}.csv")
    with open(tmp_path / "data" / "d2.npz", "wb") as fh:
        np.savez(fh, omega=OMEGA, response=_datasets()[2].response)
    (tmp_path / "data" / "broken.csv").write_text("freq,re,im\n1,2,3\n")
    (tmp_path / "data" / "notes.txt").write_text("ignored")
    return tmp_path


def _listing(path):
    return sorted(str(p.relative_to(path)) for p in path.rglob("*"))


def test_cli_batch_final_max_iter_reaches_every_fit(folder, batch_cli, capsys, monkeypatch):
    """--final-max-iter N gives each fit method=IpoptOptions(final_max_iter=N), as in
    freqid fit."""
    seen = []

    def fake(files, **kw):
        seen.append(kw["method"])
        return [BatchItem(os.path.basename(str(f)), None, "not run", "error", str(f))
                for f in files]

    monkeypatch.setattr(cli_batch, "fit_many", fake)
    cli.main(["batch", "data", "--out", "rep", "--sections", "1", "--final-max-iter", "900"])
    assert seen == [fc.IpoptOptions(final_max_iter=900)]
    code = cli.main(["batch", "data", "--out", "rep2", "--sections", "1",
                     "--final-max-iter", "0"])
    assert code == 2 and "--final-max-iter" in capsys.readouterr().err


def test_cli_batch_writes_models_and_summaries(folder, batch_cli, capsys, serial):
    code = cli.main(["batch", "data", "--out", "rep", "--sections", "1", "--jobs", "1"])
    out, err = capsys.readouterr()
    assert code == 1, err                                   # broken.csv failed
    assert "3/4 converged" in out
    assert sorted(os.listdir(folder / "rep")) == [MARKER, "models", "summary.csv", "summary.md"]
    assert sorted(os.listdir(folder / "rep" / "models")) == ["d0.json", "d1.json", "d2.json"]
    for k in range(3):
        text = (folder / "rep" / "models" / f"d{k}.json").read_text()
        assert text == serial[k].result.model.to_json() + "\n"
    md = (folder / "rep" / "summary.md").read_text().splitlines()
    assert md[0] == ("<!-- generated by: freqid batch data --out rep --sections 1 "
                     "--jobs 1 -->")
    assert any(line.startswith("| error | broken.csv |") and "unrecognised header" in line
               for line in md)
    statuses = [str(serial[k].status) for k in range(3)]
    counts = {s: statuses.count(s) for s in ("ok", "poor-fit", "not-converged")}
    assert md[4] == (f"4 files: {counts['ok']} ok, {counts['poor-fit']} poor-fit, "
                     f"{counts['not-converged']} not-converged, 1 error.")
    rows = (folder / "rep" / "summary.csv").read_text().splitlines()
    assert rows[0] == ",".join(cli_batch._COLUMNS)
    assert [r.split(",")[:2] for r in rows[1:]] == [
        ["error", "broken.csv"]] + [[s, f] for s, f in zip(statuses, ("d0.csv", "d1.csv",
                                                                       "d2.npz"))]
    assert float(rows[2].split(",")[7]) == serial[0].result.model.delay
    assert not [n for n in os.listdir(folder) if n.startswith(".")]


@pytest.mark.parametrize("argv, match", [
    (["batch", "nodir", "--out", "rep", "--sections", "1"], "data folder not found"),
    (["batch", "data/d0.csv", "--out", "rep", "--sections", "1"], "is a file, not a folder"),
    (["batch", "empty", "--out", "rep", "--sections", "1"],
     "no data files (.csv, .npz, .mat, .uff/.unv, Touchstone"),
    (["batch", "data", "--out", "exists", "--sections", "1"], "exists; pass --force"),
    (["batch", "data", "--out", "nodir/rep", "--sections", "1"], "does not exist"),
    (["batch", "data", "--out", "rep", "--sections", "0"], "--sections"),
    (["batch", "data", "--out", "rep", "--sections", "1", "--jobs", "0"], "--jobs"),
    (["batch", "data", "--out", "rep"], "--sections"),
    (["batch", "data", "--out", "rep", "--sections", "1", "--method", "x"], "invalid choice"),
])
def test_cli_batch_errors(folder, batch_cli, capsys, monkeypatch, argv, match):
    (folder / "empty").mkdir()
    (folder / "exists").mkdir()
    monkeypatch.setattr(cli_batch, "fit_many", lambda *a, **k: pytest.fail("fitted"))
    before = _listing(folder)
    code = cli.main(argv)
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert len(err.splitlines()) == 1 and err.startswith("error: ") and match in err, err
    assert _listing(folder) == before


def _interrupt_on_second_save(monkeypatch):
    calls = []
    original = fc.RationalDelayModel.save

    def save(self, path):
        calls.append(path)
        if len(calls) == 2:
            raise KeyboardInterrupt
        original(self, path)

    monkeypatch.setattr(fc.RationalDelayModel, "save", save)
    return calls


def test_keyboard_interrupt_while_writing_leaves_nothing(folder, serial, monkeypatch):
    calls = _interrupt_on_second_save(monkeypatch)
    before = _listing(folder)
    files = [os.fspath(folder / f"d{k}.csv") for k in range(4)]
    with pytest.raises(KeyboardInterrupt):
        cli_batch.write_batch_report(serial, files, "rep", command="test")
    assert len(calls) == 2
    assert _listing(folder) == before


def test_keyboard_interrupt_in_cli_keeps_the_old_folder(folder, batch_cli, capsys,
                                                        monkeypatch, serial):
    (folder / "rep").mkdir()
    (folder / "rep" / "old.txt").write_text("old")
    (folder / "rep" / MARKER).write_text("")          # a folder freqid wrote
    monkeypatch.setattr(cli_batch, "fit_many", lambda files, **kw: serial[:len(files)])
    _interrupt_on_second_save(monkeypatch)
    before = _listing(folder)
    code = cli.main(["batch", "data", "--out", "rep", "--sections", "1", "--force"])
    assert code == 130
    assert capsys.readouterr().err == "error: interrupted\n"
    assert _listing(folder) == before                   # old report intact, no temp folder


def test_keyboard_interrupt_during_fits_writes_nothing(folder, batch_cli, capsys,
                                                       monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(batch, "fit", interrupted)
    before = _listing(folder)
    assert cli.main(["batch", "data", "--out", "rep", "--sections", "1"]) == 130
    assert _listing(folder) == before


def test_duplicate_stems_get_distinct_model_files(tmp_path, serial):
    files = [os.fspath(tmp_path / "a.csv"), os.fspath(tmp_path / "a.npz")]
    cli_batch.write_batch_report(serial[:2], files, tmp_path / "out", command="t")
    assert sorted(os.listdir(tmp_path / "out" / "models")) == ["a.csv.json", "a.npz.json"]


def test_cli_batch_fits_touchstone_files_and_lists_the_tables_it_skips(tmp_path, monkeypatch,
                                                                        capsys):
    # a folder of a network analyser's .s2p files: batch read only .csv/.npz and had no
    # --parameter; a .txt beside them was named on stderr only
    monkeypatch.chdir(tmp_path)
    (tmp_path / "in").mkdir()
    f = np.geomspace(1e6, 1e9, 40)
    s = 2j * np.pi * f
    for k, gain in enumerate((0.5, 0.8)):
        s21 = gain / (1 + s / (2 * np.pi * 1e8))
        rows = "".join(f"{x!r} 0 0 {z.real!r} {z.imag!r} {z.real!r} {z.imag!r} 0 0\n"
                       for x, z in zip(f.tolist(), s21.tolist()))
        (tmp_path / "in" / f"dut{k}.s2p").write_text("# Hz S RI R 50\n" + rows)
    (tmp_path / "in" / "notes.txt").write_text("measured on the bench\n")
    code = cli.main(["batch", "in", "--parameter", "S21", "--sections", "1", "--out", "rep"])
    out, err = capsys.readouterr()
    assert code == 0, out + err
    assert "skipped 'notes.txt': a text table freqid batch does not read" in err
    text = (tmp_path / "rep" / "summary.md").read_text()
    assert "2 files: 2 ok" in text and "dut0.s2p" in text and "dut1.s2p" in text
    assert "Not fitted:\n\n- `notes.txt`: a text table freqid batch does not read" in text
    for k, gain in enumerate((0.5, 0.8)):
        model = fc.RationalDelayModel.load(tmp_path / "rep" / "models" / f"dut{k}.json")
        assert model.rational_response(np.array([1.0]))[0].real == pytest.approx(gain, rel=1e-6)

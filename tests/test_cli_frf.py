"""Tests of the ``freqid frf`` command (freqid_casadi.cli.frf): a synthetic multisine
through a known discrete-time filter, the sidecar, and bad input as FreqidError."""

import argparse
import csv
import os
import re
import shutil

import numpy as np
import pytest
from scipy import signal

from freqid_casadi.cli import app as cli
from freqid_casadi.cli import frf as cli_frf
from freqid_casadi.io.loaders import load_csv
from freqid_casadi.errors import DataError, FreqidError, OptionError

PERIOD = 256
BINS = np.arange(1, 40, 2)


def _multisine(n_periods, noise=0.0, seed=0):
    """Odd-bin multisine through y[n] = 0.5 y[n-1] + u[n] (steady state), H = 1/(1-0.5 z^-1)."""
    rng = np.random.default_rng(seed)
    spec = np.zeros(PERIOD // 2 + 1, complex)
    spec[BINS] = np.exp(2j * np.pi * rng.random(BINS.size))
    u1 = np.fft.irfft(spec, PERIOD)
    z = np.exp(2j * np.pi * np.arange(PERIOD // 2 + 1) / PERIOD)
    y1 = np.fft.irfft(spec / (1 - 0.5 / z), PERIOD)
    u = np.tile(u1, n_periods)
    y = np.tile(y1, n_periods) + noise * rng.standard_normal(PERIOD * n_periods)
    return u, y


def _write(path, u, y):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["u", "y"])
        w.writerows(zip(u.tolist(), y.tolist()))


def _args(records, out, **kw):
    ns = dict(records=str(records), period=PERIOD, fs=None, skip_periods=0, out=str(out),
              force=False)
    ns.update(kw)
    return argparse.Namespace(**ns)


def test_frf_recovers_the_filter_and_writes_the_sidecar(tmp_path):
    u, y = _multisine(4, noise=1e-4)
    _write(tmp_path / "rec.csv", u, y)
    out = tmp_path / "frf.csv"
    assert cli_frf.run_cli(_args(tmp_path / "rec.csv", out), "freqid frf") == 0
    data = load_csv(out)
    np.testing.assert_allclose(data.omega, 2 * np.pi * BINS / PERIOD, rtol=1e-12)
    exact = 1 / (1 - 0.5 * np.exp(-1j * data.omega))
    assert np.max(np.abs(data.response / exact - 1)) < 1e-2
    with open(cli_frf.stats_path(out)) as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == BINS.size
    assert [int(r["bin"]) for r in rows] == BINS.tolist()
    assert all(0.99 < float(r["coherence"]) <= 1.0 for r in rows)
    assert all(float(r["variance"]) > 0 for r in rows)


def test_frf_with_fs_and_one_period_has_no_sidecar(tmp_path):
    u, y = _multisine(1)
    _write(tmp_path / "rec.csv", u, y)
    out = tmp_path / "frf.csv"
    cli_frf.run_cli(_args(tmp_path / "rec.csv", out, fs=1000.0), "freqid frf")
    data = load_csv(out)
    np.testing.assert_allclose(data.omega, 2 * np.pi * BINS / PERIOD * 1000.0, rtol=1e-12)
    assert not (tmp_path / "frf.stats.csv").exists()


def test_parser_and_existing_output(tmp_path):
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers(dest="command")
    cli_frf.add_cli(sub)
    u, y = _multisine(2)
    _write(tmp_path / "rec.csv", u, y)
    out = tmp_path / "frf.csv"
    args = parser.parse_args(["frf", str(tmp_path / "rec.csv"), "--period", str(PERIOD),
                              "--out", str(out)])
    assert cli_frf.run_cli(args, "freqid frf") == 0
    with pytest.raises(OptionError, match="exists; pass --force"):
        cli_frf.run_cli(args, "freqid frf")
    args.force = True
    assert cli_frf.run_cli(args, "freqid frf") == 0


@pytest.mark.parametrize("content, period, match", [
    ("u,y\n1,2\n3,4\n5,6\n", 2, "not a multiple of period"),
    ("a,b\n1,2\n", 2, r"the header names the columns 'a', 'b'; choose the excitation and "
                     r"the response: input='NAME', output='NAME' \(command line --input NAME"),
    ("u,y\n1,x\n2,3\n", 2, "is not a number"),
    ("u,y\n1,1\n1,1\n1,1\n1,1\n", 2, "constant"),
])
def test_bad_records_raise_freqid_error(tmp_path, content, period, match):
    (tmp_path / "rec.csv").write_text(content)
    with pytest.raises(DataError, match=match):
        cli_frf.run_cli(_args(tmp_path / "rec.csv", tmp_path / "frf.csv", period=period),
                        "freqid frf")
    assert not (tmp_path / "frf.csv").exists()


def test_missing_file_and_folder_are_freqid_errors(tmp_path):
    with pytest.raises(FreqidError):
        cli_frf.run_cli(_args(tmp_path / "nope.csv", tmp_path / "frf.csv"), "freqid frf")
    u, y = _multisine(2)
    _write(tmp_path / "rec.csv", u, y)
    with pytest.raises(OptionError, match="does not exist"):
        cli_frf.run_cli(_args(tmp_path / "rec.csv", tmp_path / "no" / "frf.csv"), "x")


# ----------------------------------------------------------------------------- Welch H1/H2

def _filter_records(n=2 ** 14, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    return u, signal.lfilter([1.0], [1.0, -0.5], u) + 0.01 * rng.standard_normal(n)


def test_frf_h1_from_a_random_test_through_the_command_line(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    u, y = _filter_records()
    _write(tmp_path / "rec.csv", u, y)
    code = cli.main(["frf", "rec.csv", "--estimator", "h1", "--fs", "100", "--nperseg", "256",
                     "--min-coherence", "0.99", "--out", "frf.csv"])
    out, err = capsys.readouterr()
    assert code == 0 and err == "", err
    assert out.startswith("128 frequencies, 0.3906 to 50 Hz (H1, 127 segments of 256 samples)")
    data = load_csv("frf.csv")
    np.testing.assert_allclose(data.omega, 2 * np.pi * np.arange(1, 129) * 100 / 256)
    exact = 1 / (1 - 0.5 * np.exp(-1j * data.omega / 100))
    assert np.max(np.abs(data.response / exact - 1)) < 0.01
    with open(cli_frf.stats_path("frf.csv")) as fh:
        rows = list(csv.DictReader(fh))
    assert [int(r["bin"]) for r in rows] == list(range(1, 129))
    assert all(0.99 <= float(r["coherence"]) <= 1 for r in rows)


@pytest.fixture()
def actuator_copy(tmp_path):
    from freqid_casadi.experiment import ACTUATOR_FILE, dataset_path
    path = tmp_path / "0A.txt.xz"
    shutil.copyfile(dataset_path(ACTUATOR_FILE), path)
    return path


def test_frf_of_the_actuator_daq_export(actuator_copy, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code = cli.main(["frf", "0A.txt.xz", "--estimator", "h1", "--nperseg", "8192",
                     "--input", "CHANNEL2", "--output", "CHANNEL0", "--min-coherence", "0.95",
                     "--out", "frf.csv"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert out.startswith("170 frequencies, 0.1221 to 20.75 Hz (H1, 14 segments of 8192 "
                          "samples); coherence min 0.959")
    data = load_csv("frf.csv")
    assert abs(data.response[3]) == pytest.approx(0.999, abs=0.01)     # 0.49 Hz


@pytest.mark.parametrize("argv, match", [
    (["--estimator", "h1"], r"--input is required for a DAQ export: choose one of CHANNEL0, "
                            r"CHANNEL1, CHANNEL2"),
    (["--input", "CH9", "--output", "CHANNEL0"], r"--input 'CH9' is not a channel"),
    (["--input", "CHANNEL2", "--output", "CHANNEL0", "--fs", "500"],
     r"--fs 500 contradicts the file's sampling rate 1000 Hz"),
    (["--input", "CHANNEL2", "--output", "CHANNEL0", "--period", "100", "--estimator", "h2"],
     r"--period is for a periodic excitation, not --estimator h2"),
    (["--estimator", "periodic"], r"--estimator periodic needs --period N"),
    (["--input", "CHANNEL2", "--output", "CHANNEL0", "--min-coherence", "1.5"],
     r"--min-coherence: must be a number in \[0, 1\)"),
])
def test_frf_option_errors(actuator_copy, tmp_path, monkeypatch, capsys, argv, match):
    monkeypatch.chdir(tmp_path)
    code = cli.main(["frf", "0A.txt.xz", "--out", "frf.csv", *argv])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and re.search(match, err), err
    assert sorted(os.listdir(tmp_path)) == ["0A.txt.xz"]


def test_frf_refuses_to_write_onto_its_records(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    u, y = _filter_records(1024)
    _write(tmp_path / "rec.csv", u, y)
    before = (tmp_path / "rec.csv").read_bytes()
    code = cli.main(["frf", "rec.csv", "--fs", "100", "--out", "rec.csv", "--force"])
    err = capsys.readouterr().err
    assert code == 2 and "output 'rec.csv' is an input of this command" in err
    assert (tmp_path / "rec.csv").read_bytes() == before


def test_frf_h2_without_fs_is_in_rad_per_sample(tmp_path, monkeypatch, capsys):
    # H1/H2 asked for --fs where the periodic estimator falls back to rad/sample (a
    # published actuator .mat without a rate); the Welch estimate now does the same
    monkeypatch.chdir(tmp_path)
    u, y = _filter_records(4096)
    _write(tmp_path / "rec.csv", u, y)
    code = cli.main(["frf", "rec.csv", "--estimator", "h2", "--nperseg", "256", "--out",
                     "frf.csv"])
    out = capsys.readouterr().out
    assert code == 0 and "no --fs: the omega column is in rad/sample" in out
    assert "frequencies, omega 0.02454 to 3.142 rad/sample (H2" in out
    data = load_csv(tmp_path / "frf.csv")
    assert data.unit == "rad/sample"
    exact = 1 / (1 - 0.5 * np.exp(-1j * data.omega))
    assert np.median(np.abs(data.response / exact - 1)) < 0.02


@pytest.mark.parametrize("value", ["1_024", "١٠٢٤"])
def test_frf_numbers_are_ascii_decimals(tmp_path, monkeypatch, capsys, value):
    monkeypatch.chdir(tmp_path)
    u, y = _filter_records(1024)
    _write(tmp_path / "rec.csv", u, y)
    code = cli.main(["frf", "rec.csv", "--period", value, "--out", "frf.csv"])
    assert code == 2 and "--period" in capsys.readouterr().err
    assert not (tmp_path / "frf.csv").exists()


def _table(path, header, rows, units=None):
    with open(path, "w", newline="") as fh:
        fh.write(header + "\n")
        if units:
            fh.write(units + "\n")
        for row in rows:
            fh.write(",".join(row) + "\n")


@pytest.mark.parametrize("layout", ["benchmark", "scope", "time"])
def test_frf_of_a_table_whose_header_names_its_columns(tmp_path, layout):
    # published records: a benchmark's "Force","Voltage","Acceleration1",...,"Fs", (the
    # rate in the first row only, a trailing comma), an oscilloscope's CH1,CH2,Start,
    # Increment with a units line, a logger's Time,ADC,DAC; all were refused ("the first
    # line must be 'u,y'"); the columns are now chosen by name and the rate read from them
    u, y = _multisine(3)
    fs = 400.0 if layout == "benchmark" else 50000.0 if layout == "scope" else 1000.0
    n = u.size
    cells = [(repr(float(a)), "0.5", repr(float(b))) for a, b in zip(u, y)]
    if layout == "benchmark":
        _table(tmp_path / "rec.csv", '"Force","Voltage","Acceleration1","Fs",',
               [c + ((f"{fs:g}", "") if k == 0 else ("", "")) for k, c in enumerate(cells)])
        names = ("Force", "Acceleration1")
    elif layout == "scope":
        _table(tmp_path / "rec.csv", "CH1,CH2,CH3,Start,Increment,",
               [c + ("",) for c in cells], units=f"Volt,Volt,Volt,-3.92e-03,{1 / fs!r}")
        names = ("ch1", "CH3")
    else:
        _table(tmp_path / "rec.csv", "Time,ADC,DAC,SPARE",
               [(f"{k / fs!r}", c[2], c[0], "1") for k, c in enumerate(cells)])
        names = ("DAC", "ADC")
    out = tmp_path / "frf.csv"
    args = _args(tmp_path / "rec.csv", out, input=names[0], output=names[1])
    assert cli_frf.run_cli(args, "freqid frf") == 0
    data = load_csv(out)
    np.testing.assert_allclose(data.omega, 2 * np.pi * BINS / PERIOD * fs, rtol=1e-9)
    exact = 1 / (1 - 0.5 * np.exp(-1j * data.omega / fs))
    assert np.max(np.abs(data.response / exact - 1)) < 1e-9
    assert n == 3 * PERIOD
    with pytest.raises(OptionError, match=r"--fs 10 contradicts the file's sampling rate"):
        cli_frf.run_cli(_args(tmp_path / "rec.csv", tmp_path / "o2.csv", fs=10.0,
                              input=names[0], output=names[1]), "freqid frf")
    with pytest.raises(OptionError, match=r"input='Force2' is not a column of .*; its "
                       r"columns are"):
        cli_frf.run_cli(_args(tmp_path / "rec.csv", tmp_path / "o3.csv", input="Force2",
                              output=names[1]), "freqid frf")


def test_frf_warns_of_a_low_coherence(tmp_path, monkeypatch, capsys):
    # an oscilloscope's record of one step through a filter: Welch's segments are mostly
    # silence, the median coherence 0.06; the command said nothing about it
    rng = np.random.default_rng(3)
    u = rng.standard_normal(8192)
    y = rng.standard_normal(8192)                  # unrelated: coherence about 1/segments
    _write(tmp_path / "rec.csv", u, y)
    monkeypatch.chdir(tmp_path)
    assert cli.main(["frf", "rec.csv", "--fs", "1000", "--estimator", "h1", "--out",
                     "frf.csv"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"warning: the median coherence 0\.\d+ is low: most of the output is "
                     r"not explained by the input", out)
    assert "--window boxcar" in out


def test_frf_reads_one_row_of_a_matrix_of_records(tmp_path):
    # a benchmark's .mat keeps its sensors as one matrix (Acceleration, 3 x N): "--y
    # 'Acceleration' is not a time record" with no way to choose a row; each row is now a
    # record named as MATLAB indexes it
    import scipy.io

    u, y = _multisine(3)
    acc = np.vstack([0.1 * y, y, -y])
    scipy.io.savemat(tmp_path / "rec.mat", {"Force": u, "Acceleration": acc, "fs": 400.0})
    out = tmp_path / "frf.csv"
    args = _args(tmp_path / "rec.mat", out, u="Force", y="Acceleration(2,:)")
    assert cli_frf.run_cli(args, "freqid frf") == 0
    data = load_csv(out)
    exact = 1 / (1 - 0.5 * np.exp(-1j * data.omega / 400.0))
    assert np.max(np.abs(data.response / exact - 1)) < 1e-9
    with pytest.raises(OptionError, match=r"the input is one record and the output a matrix "
                       r"of 3 records \(its rows or columns\): choose one of them, e\.g\. --y "
                       r"'NAME\(2,:\)'"):
        cli_frf.run_cli(_args(tmp_path / "rec.mat", tmp_path / "o.csv", u="Force",
                              y="Acceleration"), "freqid frf")


def test_a_time_vector_with_rounded_stamps_gives_the_rate(tmp_path):
    # a published EMPS record's t steps 1 ms with a jitter of 4e-5 of a step (stamps
    # written with few digits): the rate was not read (H1 then asked for --fs); stamps
    # that are not uniform (1 % jitter) still give none
    import scipy.io

    from freqid_casadi.experiment import load_records_mat

    rng = np.random.default_rng(0)
    n = 4096
    t = np.round(np.arange(n) * 1e-3 + 4e-8 * rng.standard_normal(n), 9)
    u, y = rng.standard_normal(n), rng.standard_normal(n)
    scipy.io.savemat(tmp_path / "rec.mat", {"t": t, "u": u, "y": y})
    assert load_records_mat(tmp_path / "rec.mat").fs == pytest.approx(1000.0, rel=1e-6)
    t_bad = np.arange(n) * 1e-3 * (1 + 0.01 * rng.random(n))
    scipy.io.savemat(tmp_path / "bad.mat", {"t": np.sort(t_bad), "u": u, "y": y})
    assert load_records_mat(tmp_path / "bad.mat").fs is None


@pytest.mark.parametrize("decimal", [".", ","])
def test_frf_reads_a_labview_measurement_file(tmp_path, decimal):
    # LabVIEW's .lvm (an impact test published beside lvm_read): a header block, the
    # sample interval in Delta_X, a table after the last ***End_of_Header*** whose X_Value
    # column is empty; it was refused as "unrecognised header 'LabVIEW Measurement'"
    u, y = _multisine(3)
    dx = "0.0025" if decimal == "." else "0,0025"

    def num(v):
        return repr(float(v)).replace(".", decimal)

    head = ("LabVIEW Measurement\t\nWriter_Version\t0.92\nSeparator\tTab\n"
            f"Decimal_Separator\t{decimal}\nMulti_Headings\tNo\n***End_of_Header***\t\n\t\n"
            "Channels\t2\t\t\nSamples\t768\t768\t\nX0\t0\t0\t\n"
            f"Delta_X\t{dx}\t{dx}\t\n***End_of_Header***\t\t\t\nX_Value\tF\tacc\tComment\n")
    body = "".join(f"\t{num(a)}\t{num(b)}\n" for a, b in zip(u, y))
    (tmp_path / "test.lvm").write_text(head + body)
    out = tmp_path / "frf.csv"
    args = _args(tmp_path / "test.lvm", out, input="F", output="acc")
    assert cli_frf.run_cli(args, "freqid frf") == 0
    data = load_csv(out)
    np.testing.assert_allclose(data.omega, 2 * np.pi * BINS / PERIOD * 400.0, rtol=1e-9)
    exact = 1 / (1 - 0.5 * np.exp(-1j * data.omega / 400.0))
    assert np.max(np.abs(data.response / exact - 1)) < 1e-9


# ------------------------------------------------------------- input and output in two files

def _two_mat_files(tmp_path, u_vars, y_vars):
    import scipy.io

    scipy.io.savemat(tmp_path / "u.mat", u_vars)
    scipy.io.savemat(tmp_path / "y.mat", y_vars)
    return ["--u-file", str(tmp_path / "u.mat"), "--y-file", str(tmp_path / "y.mat")]


def test_frf_reads_the_input_and_the_output_from_two_mat_files(tmp_path, monkeypatch,
                                                                 capsys):
    # a benchmark publishes its input and its output in two files (uval as a 1 x N row in
    # one, yval in another); freqid frf took one file, so the two had to be merged by hand
    u, y = _multisine(3)
    files = _two_mat_files(tmp_path, {"uval": u[None, :]}, {"yval": y[:, None], "fs": 400.0})
    monkeypatch.chdir(tmp_path)
    assert cli.main(["frf"] + files + ["--period", str(PERIOD), "--out", "frf.csv"]) == 0
    data = load_csv(tmp_path / "frf.csv")
    np.testing.assert_allclose(data.omega, 2 * np.pi * BINS / PERIOD * 400.0, rtol=1e-12)
    exact = 1 / (1 - 0.5 * np.exp(-1j * data.omega / 400.0))
    assert np.max(np.abs(data.response / exact - 1)) < 1e-9
    assert "3 period(s) averaged" in capsys.readouterr().out
    assert (tmp_path / "frf.stats.csv").exists()
    # --fs for files that state no rate; the same records merged in one file agree
    files = _two_mat_files(tmp_path, {"uval": u}, {"yval": y})
    assert cli.main(["frf"] + files + ["--period", str(PERIOD), "--fs", "400", "--out",
                                       "frf2.csv"]) == 0
    np.testing.assert_array_equal(load_csv(tmp_path / "frf2.csv").response, data.response)


def test_two_mat_files_choose_a_record_by_name(tmp_path, monkeypatch):
    # a file of several realisations (rows of a matrix): the record is chosen with --u
    u, y = _multisine(3)
    files = _two_mat_files(tmp_path, {"uval": np.vstack([0.5 * u, u]), "r": u},
                           {"yval": y})
    monkeypatch.chdir(tmp_path)
    with pytest.raises(OptionError, match=r"--u-file '.*u\.mat' holds several records "
                       r"\(r, uval\(1,:\), uval\(2,:\)\): choose the input with --u NAME"):
        cli_frf.read_excitation(_namespace(files))
    for name, gain in (("uval(2,:)", 1.0), ("uval(1,:)", 2.0)):
        out = tmp_path / f"frf{gain:g}.csv"
        args = _namespace(files, u=name, reference="r", out=str(out))
        assert cli_frf.run_cli(args, "freqid frf") == 0
        data = load_csv(out)
        exact = gain / (1 - 0.5 * np.exp(-1j * data.omega))
        assert np.max(np.abs(data.response / exact - 1)) < 1e-9
    with pytest.raises(OptionError, match=r"--reference 'x' is not a time record of --u-file "
                       r"or --y-file; their records are r, uval\(1,:\), uval\(2,:\), yval"):
        cli_frf.read_excitation(_namespace(files, u="r", reference="x"))


def _namespace(files, **kw):
    ns = dict(records=None, u_file=files[1], y_file=files[3], period=PERIOD, fs=None,
              skip_periods=0, out="frf.csv", force=False)
    ns.update(kw)
    return argparse.Namespace(**ns)


@pytest.mark.parametrize("case, error, match", [
    ("length", DataError, r"the input 'uval' of --u-file '.*u\.mat' holds 768 samples, the "
                          r"output 'yval' of --y-file '.*y\.mat' holds 512 samples: the two "
                          r"records must cover the same samples"),
    ("rates", DataError, r"--u-file '.*u\.mat' states the sampling rate 1000 Hz, --y-file "
                         r"'.*y\.mat' 400 Hz: the input and the output must be sampled "
                         r"together"),
    ("fs", OptionError, r"--fs 10 contradicts the file's sampling rate 400 Hz; drop --fs"),
    ("name", OptionError, r"--y 'y' is not a time record of --y-file '.*y\.mat'; its "
                          r"records are yval"),
    ("text", OptionError, r"--u-file '.*rec\.csv' is not a MATLAB \.mat file"),
])
def test_two_mat_files_that_do_not_match_are_refused(tmp_path, case, error, match):
    u, y = _multisine(3)
    u_vars = {"uval": u, "fs": 1000.0} if case == "rates" else {"uval": u}
    y_vars = {"yval": y[:512] if case == "length" else y, "fs": 400.0}
    files = _two_mat_files(tmp_path, u_vars, y_vars)
    kw = {"fs": 10.0} if case == "fs" else {"y": "y"} if case == "name" else {}
    if case == "text":
        _write(tmp_path / "rec.csv", u, y)
        files[1] = str(tmp_path / "rec.csv")
    with pytest.raises(error, match=match):
        cli_frf.run_cli(_namespace(files, out=str(tmp_path / "frf.csv"), **kw), "freqid frf")
    assert not (tmp_path / "frf.csv").exists()


@pytest.mark.parametrize("argv, match", [
    (["--u-file", "u.mat"], r"--u-file needs --y-file: pass the input's file and the "
                            r"output's file"),
    (["--y-file", "y.mat"], r"--y-file needs --u-file"),
    (["rec.mat", "--u-file", "u.mat", "--y-file", "y.mat"],
     r"RECORDS 'rec\.mat' and --u-file/--y-file both give the records"),
    ([], r"no records given: pass RECORDS \(a file holding the input and the output\), or "
         r"the two files: --u-file U\.mat --y-file Y\.mat"),
])
def test_records_are_one_file_or_two(tmp_path, monkeypatch, capsys, argv, match):
    monkeypatch.chdir(tmp_path)
    assert cli.main(["frf"] + argv + ["--out", "frf.csv"]) != 0
    assert re.search(match, capsys.readouterr().err)


def test_load_records_mat_of_a_file_holding_one_record(tmp_path):
    import scipy.io

    from freqid_casadi.experiment import load_records_mat

    u, _ = _multisine(1)
    scipy.io.savemat(tmp_path / "u.mat", {"uval": u[None, :], "t": np.arange(u.size) / 50.0})
    with pytest.raises(DataError, match=r"holds no time records \(two or more real vectors "
                       r"of one length\)"):
        load_records_mat(tmp_path / "u.mat")
    rec = load_records_mat(tmp_path / "u.mat", min_records=1)
    assert list(rec.channels) == ["uval"] and rec.fs == pytest.approx(50.0)
    np.testing.assert_array_equal(rec.channels["uval"], u)
    scipy.io.savemat(tmp_path / "t.mat", {"t": np.arange(64.0)})
    with pytest.raises(DataError, match=r"holds no time records \(a real vector of 16 or more "
                       r"samples\): found t \(64,\)"):
        load_records_mat(tmp_path / "t.mat", min_records=1)
    with pytest.raises(OptionError, match="min_records must be 1 or 2, got 3"):
        load_records_mat(tmp_path / "u.mat", min_records=3)


# ------------------------------------------------- LabVIEW measurement files of several segments

_LVM_HEAD = ("LabVIEW Measurement\t\nWriter_Version\t2\nReader_Version\t2\nSeparator\tTab\n"
             "Decimal_Separator\t{dec}\nMulti_Headings\t{multi}\nX_Columns\tNo\n"
             "Time_Pref\tAbsolute\nOperator\tlab\nDate\t2024/01/31\nTime\t23:59:58.5\n"
             "***End_of_Header***\t\n\t\n")


def _segment_text(names, columns, dx, date="2024/01/31", time="23:59:59.000000", dec="."):
    """A segment as LabVIEW writes one (header block, heading, rows, a blank line); ``dx``
    one Delta_X per channel."""
    def num(v):
        return repr(float(v)).replace(".", dec)

    n = len(names)
    row = "\t".join
    head = (row(["Channels", str(n)] + [""] * n) + "\n"
            + row(["Samples"] + [str(len(columns[0]))] * n + [""]) + "\n"
            + row(["Date"] + [date] * n + [""]) + "\n"
            + row(["Time"] + [time.replace(".", dec)] * n + [""]) + "\n"
            + row(["X0"] + ["0.0000000000000000E+0".replace(".", dec)] * n + [""]) + "\n"
            + row(["Delta_X"] + [num(d) for d in dx] + [""]) + "\n"
            + row(["***End_of_Header***"] + [""] * (n + 1)) + "\n"
            + row(["X_Value"] + list(names) + ["Comment"]) + "\n")
    body = "".join("\t" + "\t".join(num(v) for v in vals) + "\n" for vals in zip(*columns))
    return head + body + "\t\n"


def _three_segments(tmp_path, gap=0.0, dec=".", name="rec.lvm"):
    """One period (256 samples at 400 Hz: 0.64 s) of the multisine in each of 3 segments
    that start at 23:59:59.00, 59.64 and 00:00:00.28 the next day (+ ``gap`` s from the
    second on)."""
    u, y = _multisine(1)
    times = [("2024/01/31", f"23:59:59.{0:06d}"), ("2024/01/31", f"23:59:59.{640000:06d}"),
             ("2024/02/01", f"00:00:00.{280000:06d}")]
    text = _LVM_HEAD.format(dec=dec, multi="Yes")
    for k, (date, time) in enumerate(times):
        if k and gap:
            h, m, s = time.split(":")
            time = f"{h}:{m}:{float(s) + gap:09.6f}"
        text += _segment_text(("F", "acc", "T"), (u, y, 20 + u), (0.0025,) * 3, date, time,
                              dec)
    (tmp_path / name).write_text(text)
    return tmp_path / name


@pytest.mark.parametrize("dec", [".", ","])
def test_frf_joins_the_segments_of_a_labview_file(tmp_path, monkeypatch, capsys, dec):
    # a .lvm written with one header per segment (a header before each call of LabVIEW's
    # writer) was refused ("several segments: save one segment per file"); the segments
    # are now pieces of one record, joined in file order, and a note says so
    _three_segments(tmp_path, dec=dec)
    monkeypatch.chdir(tmp_path)
    assert cli.main(["frf", "rec.lvm", "--input", "F", "--output", "acc", "--period",
                     str(PERIOD), "--out", "frf.csv"]) == 0
    out = capsys.readouterr().out
    assert ("LabVIEW file: 3 segments joined end to end (256 samples each, 768 in all); "
            "--lvm-segment K reads one alone") in out
    assert "their time stamps make one continuous acquisition" in out
    assert "3 period(s) averaged" in out
    data = load_csv(tmp_path / "frf.csv")
    np.testing.assert_allclose(data.omega, 2 * np.pi * BINS / PERIOD * 400.0, rtol=1e-9)
    exact = 1 / (1 - 0.5 * np.exp(-1j * data.omega / 400.0))
    assert np.max(np.abs(data.response / exact - 1)) < 1e-9
    assert (tmp_path / "frf.stats.csv").exists()


def test_segments_with_a_gap_are_joined_with_a_warning(tmp_path, monkeypatch, capsys):
    _three_segments(tmp_path, gap=1.25)
    monkeypatch.chdir(tmp_path)
    assert cli.main(["frf", "rec.lvm", "--input", "F", "--output", "acc", "--period",
                     str(PERIOD), "--out", "frf.csv"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"warning: segment 2 starts 1\.25 s after segment 1 ends \(Date/Time\): "
                     r"separate acquisitions, joined as one record; .* pass --lvm-segment K "
                     r"to read one alone", out)
    data = load_csv(tmp_path / "frf.csv")     # whole periods in each: still the filter
    exact = 1 / (1 - 0.5 * np.exp(-1j * data.omega / 400.0))
    assert np.max(np.abs(data.response / exact - 1)) < 1e-9


def test_lvm_segment_reads_one_segment(tmp_path, monkeypatch, capsys):
    path = _three_segments(tmp_path)
    monkeypatch.chdir(tmp_path)
    assert cli.main(["frf", "rec.lvm", "--input", "F", "--output", "acc", "--period",
                     str(PERIOD), "--lvm-segment", "2", "--out", "frf.csv"]) == 0
    out = capsys.readouterr().out
    assert "LabVIEW file: segment 2 of 3 read (line 286, 256 samples)" in out
    assert "1 period(s) averaged" in out
    data = load_csv(tmp_path / "frf.csv")
    exact = 1 / (1 - 0.5 * np.exp(-1j * data.omega / 400.0))
    assert np.max(np.abs(data.response / exact - 1)) < 1e-9
    assert path.read_text().splitlines()[285] == "X_Value\tF\tacc\tT\tComment"
    for argv, match in ((["--lvm-segment", "4"], r"segment=4 \(command line --lvm-segment "
                                                 r"4\): 'rec\.lvm' holds 3 segment\(s\); "
                                                 r"choose 1 to 3"),
                        (["--lvm-segment", "0"], r"--lvm-segment: must be an integer >= 1")):
        assert cli.main(["frf", "rec.lvm", "--input", "F", "--output", "acc", "--period",
                         str(PERIOD), "--out", "o.csv"] + argv) != 0
        assert re.search(match, capsys.readouterr().err)
    _write(tmp_path / "rec.csv", *_multisine(2))
    assert cli.main(["frf", "rec.csv", "--period", str(PERIOD), "--lvm-segment", "1",
                     "--out", "o.csv"]) != 0
    assert re.search(r"--lvm-segment chooses a segment of a LabVIEW measurement file .*; "
                     r"RECORDS 'rec\.csv' is not one: drop --lvm-segment",
                     capsys.readouterr().err)


def test_segments_that_differ_are_refused_naming_them(tmp_path):
    # a segment from another source (other channels) or at another rate cannot be joined;
    # the message names the segment and says how to read one
    from freqid_casadi.experiment import load_records_table

    u, y = _multisine(1)
    head = _LVM_HEAD.format(dec=".", multi="Yes")
    seg = _segment_text(("F", "acc"), (u, y), (0.0025, 0.0025))
    other = _segment_text(("V", "acc"), (u, y), (0.0025, 0.0025))
    slow = _segment_text(("F", "acc"), (u, y), (0.005, 0.005))
    (tmp_path / "a.lvm").write_text(head + seg + seg + other)
    with pytest.raises(OptionError, match=r"input='F' is not a column of segment 3 \(line "
                       r"\d+\) of '.*a\.lvm', one of its 3 segments: its columns are "
                       r"'X_Value', 'V', 'acc', 'Comment'; read one segment with segment=K "
                       r"\(command line --lvm-segment K\)"):
        load_records_table(tmp_path / "a.lvm", "F", "acc")
    u2, y2, fs = load_records_table(tmp_path / "a.lvm", "V", "acc", segment=3)
    np.testing.assert_array_equal(u2, u)
    assert fs == 400.0
    (tmp_path / "b.lvm").write_text(head + seg + slow)
    with pytest.raises(DataError, match=r"the segments of '.*b\.lvm' differ in sampling: "
                       r"segment 1 at 400 Hz, segment 2 at 200 Hz \(Delta_X\); read one "
                       r"segment with segment=K"):
        load_records_table(tmp_path / "b.lvm", "F", "acc")
    assert load_records_table(tmp_path / "b.lvm", "F", "acc", segment=2)[2] == 200.0
    with pytest.raises(OptionError, match="segment must be a segment number"):
        load_records_table(tmp_path / "b.lvm", "F", "acc", segment=True)
    _write(tmp_path / "rec.csv", u, y)
    with pytest.raises(OptionError, match=r"segment=1 \(command line --lvm-segment\) chooses "
                       r"a segment of a LabVIEW measurement file"):
        load_records_table(tmp_path / "rec.csv", segment=1)


def test_the_rate_is_the_chosen_columns_delta_x(tmp_path):
    # LabVIEW gives Delta_X per channel (a slow channel beside fast ones: 1 s beside 2.5
    # ms); the rate is the chosen columns', not the first one's; two chosen columns at
    # different rates are refused
    from freqid_casadi.experiment import load_records_table

    u, y = _multisine(1)
    text = _LVM_HEAD.format(dec=".", multi="No") + _segment_text(
        ("T", "F", "acc"), (u, u, y), (1.0, 0.0025, 0.0025))
    (tmp_path / "c.lvm").write_text(text)
    assert load_records_table(tmp_path / "c.lvm", "F", "acc")[2] == 400.0
    with pytest.raises(DataError, match=r"segment 1: the input column 'T' is sampled at 1 Hz, "
                       r"the output 'acc' at 400 Hz \(Delta_X\)"):
        load_records_table(tmp_path / "c.lvm", "T", "acc")


def test_lvm_segments_describes_the_segments(tmp_path):
    from freqid_casadi.experiment import load_records_table, lvm_segments

    segs = lvm_segments(_three_segments(tmp_path))
    u1, y1 = _multisine(1)
    u, y, fs = load_records_table(tmp_path / "rec.lvm", "F", "acc")
    np.testing.assert_array_equal(u, np.tile(u1, 3))
    np.testing.assert_array_equal(y, np.tile(y1, 3))
    assert fs == 400.0
    assert [s.number for s in segs] == [1, 2, 3]
    assert [s.samples for s in segs] == [PERIOD] * 3
    assert all(s.columns == ("X_Value", "F", "acc", "T", "Comment") for s in segs)
    assert all(s.fs == 400.0 for s in segs)
    midnight = 86400.0
    np.testing.assert_allclose([s.start for s in segs],
                               [midnight - 1.0, midnight - 0.36, midnight + 0.28], atol=1e-9)
    # one header, the rows of later calls appended to its table (Multi_Headings No, as
    # LabVIEW writes "one header only"): one segment of all the rows; a special block is
    # skipped
    u, y = _multisine(3)
    text = (_LVM_HEAD.format(dec=".", multi="No")
            + _segment_text(("F", "acc"), (u, y), (0.0025, 0.0025)).replace(
                "Samples\t768\t768", "Samples\t256\t256"))
    lines = text.splitlines(keepends=True)
    at = len(lines) - 300
    text = "".join(lines[:at] + ["***Start_Special***\n", "note\tfrom the operator\n",
                                 "***End_Special***\n"] + lines[at:])
    (tmp_path / "one.lvm").write_text(text)
    (seg,) = lvm_segments(tmp_path / "one.lvm")
    assert seg.samples == 3 * PERIOD and seg.number == 1
    out = tmp_path / "frf.csv"
    assert cli_frf.run_cli(_args(tmp_path / "one.lvm", out, input="F", output="acc"), "x") == 0
    data = load_csv(out)
    exact = 1 / (1 - 0.5 * np.exp(-1j * data.omega / 400.0))
    assert np.max(np.abs(data.response / exact - 1)) < 1e-9
    _write(tmp_path / "rec.csv", u, y)
    with pytest.raises(DataError, match="is not a LabVIEW measurement file"):
        lvm_segments(tmp_path / "rec.csv")


def test_a_labview_file_with_comma_separated_columns(tmp_path):
    # LabVIEW writes "Separator Comma" files too (X_Columns One: a time column first); the
    # header was split at tabs only, so Delta_X was not found and the rate was lost
    from freqid_casadi.experiment import load_records_table

    u, y = _multisine(2)
    text = ("LabVIEW Measurement,\nWriter_Version,2\nReader_Version,2\nSeparator,Comma\n"
            "Decimal_Separator,.\nMulti_Headings,Yes\nX_Columns,One\n***End_of_Header***,\n,\n"
            "Channels,2,,\nSamples,512,512,\nDate,2024/04/10,2024/04/10,\n"
            "Time,13:06:46.26,13:06:46.26,\nDelta_X,2.000000E-6,2.000000E-6,\n"
            "***End_of_Header***,,,\nX_Value,Ch A,Ch B,Comment\n"
            + "".join(f"{k * 2e-6!r},{a!r},{b!r}\n"
                      for k, (a, b) in enumerate(zip(u.tolist(), y.tolist()))))
    (tmp_path / "c.lvm").write_text(text)
    u2, y2, fs = load_records_table(tmp_path / "c.lvm", "ch a", "Ch B")
    np.testing.assert_array_equal(u2, u)
    np.testing.assert_array_equal(y2, y)
    assert fs == pytest.approx(5e5, rel=1e-12)


def test_lines_of_the_grid_below_the_threshold_are_named_and_fill_grid_keeps_them(
        tmp_path, monkeypatch, capsys):
    # the odd-bin multisine with two lines 25 dB down (a measured force dipping at a
    # resonance): left out by the -20 dB threshold, named with their level, kept by
    # --fill-grid; --threshold 30 keeps them too (no other line is near)
    monkeypatch.chdir(tmp_path)
    u, y = _multisine(2)
    U = np.fft.rfft(u[:PERIOD])
    dips = [15, 17]
    for k in dips:
        U[k] *= 10 ** (-25 / 20)
    scale = np.ones(PERIOD // 2 + 1)
    scale[dips] = 10 ** (-25 / 20)
    u1 = np.fft.irfft(U, PERIOD)
    y1 = np.fft.irfft(np.fft.rfft(y[:PERIOD]) * scale, PERIOD)
    _write(tmp_path / "rec.csv", np.tile(u1, 2), np.tile(y1, 2))
    assert cli.main(["frf", "rec.csv", "--period", str(PERIOD), "--out", "a.csv"]) == 0
    out = capsys.readouterr().out
    assert "note: 2 line(s) of the excitation's grid (odd bins) inside the band" in out
    assert "bins 15 (-25 dB), 17 (-25 dB)" in out and "pass --fill-grid" in out
    assert load_csv("a.csv").n_points == BINS.size - 2
    for extra in (["--fill-grid"], ["--threshold", "30"]):
        assert cli.main(["frf", "rec.csv", "--period", str(PERIOD), "--out", "b.csv",
                         "--force"] + extra) == 0
        out = capsys.readouterr().out
        assert "note:" not in out
        data = load_csv("b.csv")
        np.testing.assert_allclose(data.omega, 2 * np.pi * BINS / PERIOD, rtol=1e-12)
        exact = 1 / (1 - 0.5 * np.exp(-1j * data.omega))
        assert np.max(np.abs(data.response / exact - 1)) < 1e-9
    assert "--fill-grid: kept 2 line(s)" in (cli.main(
        ["frf", "rec.csv", "--period", str(PERIOD), "--out", "c.csv", "--fill-grid"]) == 0
        and capsys.readouterr().out)


def test_fill_grid_gives_the_robot_arms_lines(tmp_path, monkeypatch, capsys):
    # DaISy 96-009: the measured torque dips at the arm's first resonance (bins 59, 61);
    # with --fill-grid the command gives the 101 odd lines experiment.robot_arm() keeps
    from freqid_casadi.experiment import ROBOT_ARM_FILE, dataset_path, robot_arm
    monkeypatch.chdir(tmp_path)
    shutil.copyfile(dataset_path(ROBOT_ARM_FILE), "robot_arm.dat")
    assert cli.main(["frf", "robot_arm.dat", "--period", "1024", "--out", "a.csv"]) == 0
    assert "bins 59 (-29.3 dB), 61 (-22.2 dB)" in capsys.readouterr().out
    assert load_csv("a.csv").n_points == 99
    assert cli.main(["frf", "robot_arm.dat", "--period", "1024", "--out", "b.csv",
                     "--fill-grid"]) == 0
    data, ref = load_csv("b.csv"), robot_arm().data
    np.testing.assert_allclose(data.omega, ref.omega, rtol=1e-15)
    np.testing.assert_allclose(data.response, ref.response, rtol=1e-12)


@pytest.mark.parametrize("argv, match", [
    (["--threshold", "0"], "--threshold: must be a finite number of decibels > 0"),
    (["--threshold", "x"], "--threshold"),
    (["--fill-grid", "--estimator", "h1", "--fs", "100"], None),
])
def test_threshold_and_fill_grid_option_errors(tmp_path, monkeypatch, capsys, argv, match):
    monkeypatch.chdir(tmp_path)
    u, y = _multisine(2)
    _write(tmp_path / "rec.csv", u, y)
    base = ["frf", "rec.csv", "--out", "a.csv"]
    if "--estimator" not in argv:
        base += ["--period", str(PERIOD)]
    code = cli.main(base + argv)
    err = capsys.readouterr().err
    if match is None:               # --fill-grid is for a periodic excitation
        assert code == 2 and "--fill-grid is for --estimator periodic" in err
    else:
        assert code == 2 and match in err

"""Malformed input through the API and the CLI: one table of cases.

Every case raises a typed :class:`~freqid_casadi.errors.FreqidError` from the API, and the
same input through ``freqid fit`` prints one ``error: ...`` line and exits 2. The message
names the problem (``match``) and, where the table gives one, the fix (``fix``). No case
leaves a file behind.

A real-valued response is valid data (phase 0): it is accepted alike from arrays, .npz and
CSV (with an explicit ``imag`` column of zeros); a CSV without the ``imag`` column is
rejected by its header.
"""

import os
import re
import warnings
from dataclasses import dataclass, field

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.cli import app as cli
from freqid_casadi.report import folder as report
from freqid_casadi.errors import DataError, FreqidError, OptionError, StructureError
from conftest import first_order_response  # noqa: E402

W = np.logspace(-1, 2, 30)
RESP = first_order_response(W)     # valid data: gain, delay, one pole


def _with(arr, idx, value, dtype=float):
    out = np.array(arr, dtype=dtype)
    out[idx] = value
    return out


@dataclass(frozen=True)
class Case:
    """One malformed input.

    kind "arrays": ``fit(omega, response, n_sections=1, **fit_kw)``; the CLI gets the arrays
    in an .npz file. kind "file": ``load(path)`` of the file ``make`` writes (``name``);
    the CLI fits it. kind "option": valid data with ``fit_kw``; ``cli`` is the CLI's
    arguments after ``fit data.npz --out rep`` (None: no CLI equivalent).
    """

    id: str
    kind: str
    exc: type
    match: str
    fix: str = None
    omega: object = None
    response: object = None
    fit_kw: dict = field(default_factory=dict)
    name: str = None
    make: object = None
    cli: tuple = ("--sections", "1")


def _text(text, name="bad.csv"):
    return dict(name=name, make=lambda p: p.write_text(text))


def _bytes(payload, name):
    return dict(name=name, make=lambda p: p.write_bytes(payload))


def _npz(name="bad.npz", **arrays):
    def make(p):
        with open(p, "wb") as fh:
            np.savez(fh, **arrays)
    return dict(name=name, make=make)


def _npy_as_npz(p):
    with open(p, "wb") as fh:
        np.save(fh, W)


GOOD_CSV = "omega,real,imag\n" + "".join(f"{w!r},{z.real!r},{z.imag!r}\n"
                                         for w, z in zip(W.tolist(), RESP.tolist()))

CASES = [
    # ---- arrays: frequencies
    Case("omega-nan", "arrays", DataError, r"omega must be finite: omega\[3\]=nan",
         "remove that point", omega=_with(W, 3, np.nan), response=RESP),
    Case("omega-inf", "arrays", DataError, r"omega must be finite: omega\[29\]=inf",
         "remove", omega=_with(W, 29, np.inf), response=RESP),
    Case("omega-unsorted", "arrays", DataError, r"strictly increasing.*omega\[6\]",
         r"FrequencyData\.sorted", omega=W[[0, 1, 2, 3, 4, 6, 5, *range(7, 30)]],
         response=RESP),
    Case("omega-duplicate", "arrays", DataError, r"duplicated value.*omega\[5\]",
         r"FrequencyData\.sorted", omega=_with(W, 5, W[4]), response=RESP),
    Case("omega-zero", "arrays", DataError, r"omega must be > 0.*omega\[0\]=0\.0",
         "drop the zero", omega=_with(W, 0, 0.0), response=RESP,
         cli=None),                                 # files: zero rows dropped with a note
    Case("omega-negative", "arrays", DataError, r"omega must be > 0.*omega\[0\]=-1\.0",
         "drop the zero/negative", omega=_with(W, 0, -1.0), response=RESP),
    Case("omega-zero-with-integrator", "arrays", DataError, r"omega\[0\]=0\.0",
         "an integrator is a model option", omega=_with(W, 0, 0.0), response=RESP,
         fit_kw=dict(integrator=True), cli=None),
    Case("omega-complex", "arrays", DataError, "omega must be real", None,
         omega=W + 1j, response=RESP),
    Case("omega-2d", "arrays", DataError, "omega must be one-dimensional", None,
         omega=W.reshape(5, 6), response=RESP),
    Case("omega-text", "arrays", DataError, "omega must be an array of numbers", None,
         omega=np.array(["a"] * 30), response=RESP),
    # ---- arrays: responses and lengths
    Case("response-nan", "arrays", DataError, r"response must be finite: response\[7\]",
         "remove or re-measure", omega=W, response=_with(RESP, 7, np.nan, complex)),
    Case("response-inf", "arrays", DataError, r"response must be finite: response\[0\]",
         "re-measure", omega=W, response=_with(RESP, 0, complex(np.inf, 0), complex)),
    Case("response-zero", "arrays", DataError, r"response must be nonzero.*response\[2\]=0",
         "remove that point", omega=W, response=_with(RESP, 2, 0, complex)),
    Case("length-mismatch", "arrays", DataError,
         r"equal lengths: len\(omega\)=30, len\(response\)=29", "one response value per",
         omega=W, response=RESP[:-1]),
    Case("empty", "arrays", DataError, "omega is empty", "at least a few",
         omega=np.array([]), response=np.array([], complex)),
    Case("one-point", "arrays", DataError, "too few data points for 1 sections: 1 points",
         "even one section needs 8 points: measure more frequencies", omega=W[:1],
         response=RESP[:1]),
    Case("more-parameters-than-data", "arrays", DataError,
         "too few data points for 3 sections: 12 points for 20 parameters",
         r"at most 1\) or more data", omega=W[:12], response=RESP[:12],
         fit_kw=dict(n_sections=3), cli=("--sections", "3")),
    # ---- files
    Case("csv-missing-column", "file", DataError, "unrecognised header 'omega,real'",
         "first line must be 'omega,real,imag'", **_text("omega,real\n1,2\n2,3\n")),
    # (an unknown column beside a complete response is left out with a note; beside an
    # incomplete one the header stays refused)
    Case("csv-unknown-columns", "file", DataError, "unrecognised header 'omega,real,x,y'",
         "first line must be", **_text("omega,real,x,y\n1,2,3,4\n")),
    Case("csv-bad-header", "file", DataError, "unrecognised header 'freq,re,x'",
         "'omega,magnitude_db,phase_deg'", **_text("freq,re,x\n1,2,3\n")),
    Case("csv-freq-without-unit", "file", DataError, "the frequency unit is unknown",
         "freq_unit='Hz'", **_text("freq,re,im\n1,2,3\n")),
    Case("csv-no-header", "file", DataError, "frequency unit is unknown .it has no header",
         "--freq-unit hz", **_text("1,2,3\n2,3,4\n")),
    Case("csv-short-row", "file", DataError, "line 3: expected 3 columns.*got 2", None,
         **_text("omega,real,imag\n1,2,3\n2,3\n")),
    Case("csv-long-row", "file", DataError, "line 2: expected 3 columns.*got 4", None,
         **_text("omega,real,imag\n1,2,3,4\n")),
    Case("csv-non-numeric", "file", DataError, "line 3, column 'real': 'abc' is not a number",
         None, **_text("omega,real,imag\n1,2,3\n2,abc,4\n")),
    Case("csv-empty-cell", "file", DataError, "column 'imag': '' is not a number", None,
         **_text("omega,real,imag\n1,2,\n")),
    Case("csv-nan-cell", "file", DataError, "response must be finite", "re-measure",
         **_text("omega,real,imag\n1,2,3\n2,nan,4\n")),
    Case("csv-unsorted", "file", DataError, "strictly increasing", r"FrequencyData\.sorted",
         **_text("omega,real,imag\n2,2,3\n3,2,4\n1,2,4\n")),
    Case("csv-empty-file", "file", DataError, "is empty", "expected a header",
         **_text("")),
    Case("csv-header-only", "file", DataError, "has a header but no data rows", None,
         **_text("omega,real,imag\n# only a comment\n")),
    Case("csv-binary", "file", DataError, r"not a text CSV file \(not UTF-8\)", None,
         **_bytes(b"\xff\xfe\x00\x81binary", "bad.csv")),
    Case("npz-missing-array", "file", DataError, r"lacks array\(s\) \['response'\]",
         r"np\.savez\(path, omega=omega, response=response\)", **_npz(omega=W)),
    Case("npz-corrupt", "file", DataError, "cannot read .* as .npz", None,
         **_bytes(b"PK\x03\x04 not really a zip", "bad.npz")),
    Case("npz-is-npy", "file", DataError, r"single array \(\.npy\)", r"np\.savez",
         name="bad.npz", make=_npy_as_npz),
    Case("npz-bad-values", "file", DataError, "omega must be > 0", "drop the zero",
         **_npz(omega=-W, response=RESP)),
    Case("missing-file", "file", DataError, "data file not found: .*nothere.csv",
         "check the path", name="nothere.csv", make=lambda p: None),
    Case("directory", "file", DataError, "is a directory, not a data file",
         "name the file inside it", name="adir.csv", make=lambda p: p.mkdir()),
    # ---- options
    Case("n-sections-zero", "option", StructureError, "n_sections must be >= 1, got 0", None,
         fit_kw=dict(n_sections=0), cli=("--sections", "0")),
    Case("n-sections-negative", "option", StructureError, "n_sections must be >= 1, got -2",
         None, fit_kw=dict(n_sections=-2), cli=("--sections", "-2")),
    Case("n-sections-float", "option", StructureError,
         "n_sections must be a positive integer, got 1.5", None,
         fit_kw=dict(n_sections=1.5), cli=("--sections", "1.5")),
    Case("tol-negative", "option", OptionError, r"tol must be a number > 0.*got -0\.1", None,
         fit_kw=dict(tol=-0.1), cli=("--sections", "1", "--tol", "-0.1")),
    Case("tol-nan", "option", OptionError, "tol must be a number > 0", None,
         fit_kw=dict(tol=float("nan")), cli=("--sections", "1", "--tol", "nan")),
    Case("method-unknown", "option", OptionError, "unknown method 'newton'",
         "choose one of ipopt, barrier-lm", fit_kw=dict(method="newton"),
         cli=("--sections", "1", "--method", "newton")),
    Case("basis-unknown", "option", OptionError, "unknown basis 'third-order'",
         "choose one of second-order, first-order", fit_kw=dict(basis="third-order"),
         cli=("--sections", "1", "--basis", "third-order")),
    Case("weights-negative", "option", DataError, r"weights must be finite and >= 0", None,
         fit_kw=dict(weights=_with(np.ones(30), 4, -1.0)), cli=None),
    Case("weights-all-zero", "option", DataError, "weights are all zero", None,
         fit_kw=dict(weights=np.zeros(30)), cli=None),
]

CLI_MATCH = {   # argparse words the same problems its own way
    "n-sections-zero": "--sections: must be a positive integer",
    "n-sections-negative": "--sections: must be a positive integer",
    "n-sections-float": "--sections: must be a positive integer or 'auto', got '1.5'",
    "tol-negative": "--tol: must be a finite number > 0",
    "tol-nan": "--tol: must be a finite number > 0",
    "method-unknown": "invalid choice: 'newton'",
    "basis-unknown": "invalid choice: 'third-order'",
}


#: known bugs of other modules (reported), kept strict so the fix is noticed
KNOWN_BUGS = {}


def _params(cases):
    return [pytest.param(c, id=c.id, marks=[pytest.mark.xfail(strict=True,
                                                                reason=KNOWN_BUGS[c.id])]
                         if c.id in KNOWN_BUGS else []) for c in cases]


def test_the_table_is_large_enough():
    assert len(CASES) >= 25
    assert len({c.id for c in CASES}) == len(CASES)


def _api_call(case, folder):
    if case.kind == "arrays":
        kw = {"n_sections": 1, **case.fit_kw}
        return lambda: fc.fit(case.omega, case.response, **kw)
    if case.kind == "file":
        path = folder / case.name
        case.make(path)
        return lambda: fc.load(path)
    kw = {"n_sections": 1, **case.fit_kw}
    return lambda: fc.fit(fc.FrequencyData(W, RESP), **kw)


def _listing(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


@pytest.mark.parametrize("case", _params(CASES))
def test_api_raises_a_typed_error_naming_problem_and_fix(case, tmp_path):
    call = _api_call(case, tmp_path)
    before = _listing(tmp_path)
    with pytest.raises(case.exc, match=case.match) as info:
        call()
    assert isinstance(info.value, FreqidError)
    assert isinstance(info.value, (ValueError, RuntimeError))       # a builtin too
    if case.fix:
        assert re.search(case.fix, str(info.value)), str(info.value)
    assert _listing(tmp_path) == before


def _cli_file(case, folder):
    if case.kind == "file":
        case.make(folder / case.name)
        return case.name
    omega = W if case.kind == "option" else case.omega
    response = RESP if case.kind == "option" else case.response
    with open(folder / "data.npz", "wb") as fh:
        np.savez(fh, omega=omega, response=response)
    return "data.npz"


@pytest.mark.parametrize("case", _params([c for c in CASES if c.cli is not None]))
def test_cli_prints_one_error_line_and_exits_2(case, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    name = _cli_file(case, tmp_path)
    before = _listing(tmp_path)
    code = cli.main(["fit", name, "--out", "rep", *case.cli])
    out, err = capsys.readouterr()
    assert code == 2
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err and out == ""
    assert re.search(CLI_MATCH.get(case.id, case.match), lines[0]), lines[0]
    if case.fix and case.id not in CLI_MATCH:
        assert re.search(case.fix, lines[0]), lines[0]
    assert _listing(tmp_path) == before                  # no report, no temporary folder


# ----------------------------------------------------------------------------- real data


def test_real_response_is_valid_data_with_phase_zero(tmp_path):
    """A real response is accepted alike from arrays, .npz and CSV (imag column of zeros)
    and equals the complex data with zero imaginary part; a CSV lacking the imag column is
    rejected by its header, not read as phase 0."""
    real = np.abs(RESP)
    a = fc.FrequencyData(W, real)
    assert a.response.dtype == complex and np.all(a.response.imag == 0)
    with open(tmp_path / "r.npz", "wb") as fh:
        np.savez(fh, omega=W, response=real)
    b = fc.load(tmp_path / "r.npz")
    fc.save_csv(a, tmp_path / "r.csv")
    c = fc.load(tmp_path / "r.csv")
    (tmp_path / "mp.csv").write_text("omega,magnitude_db,phase_deg\n" + "".join(
        f"{w!r},{float(20 * np.log10(m))!r},0\n" for w, m in zip(W.tolist(), real.tolist())))
    d = fc.load(tmp_path / "mp.csv")
    for x in (b, c):
        assert np.array_equal(x.omega, a.omega) and np.array_equal(x.response, a.response)
    assert np.allclose(d.response, a.response, rtol=1e-12) and np.all(d.response.imag == 0)
    (tmp_path / "r2.csv").write_text("omega,real\n1,2\n2,3\n")
    with pytest.raises(DataError, match="unrecognised header 'omega,real'"):
        fc.load(tmp_path / "r2.csv")
    # and it fits: a pure gain of 2 with phase 0 needs no delay
    res = fc.fit(fc.FrequencyData(W, np.full(30, 2.0)), n_sections=1)
    assert res.max_rel_error < 1e-6 and res.model.delay < 1e-6


# ----------------------------------------------------------------------------- files


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0,
                    reason="running as root: chmod 000 does not stop root from reading")
def test_unreadable_file(tmp_path):
    path = tmp_path / "locked.csv"
    path.write_text(GOOD_CSV)
    path.chmod(0)
    try:
        with pytest.raises(DataError, match="not readable; check its permissions"):
            fc.load(path)
    finally:
        path.chmod(0o600)


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0,
                    reason="running as root: a read-only folder does not stop root writing")
def test_unwritable_output_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "data.csv").write_text(GOOD_CSV)
    (tmp_path / "ro").mkdir()
    (tmp_path / "ro").chmod(0o500)
    try:
        code = cli.main(["fit", "data.csv", "--sections", "1", "--out", "ro/rep"])
        err = capsys.readouterr().err
        assert code == 2 and err.startswith("error: ") and len(err.splitlines()) == 1
        assert os.listdir(tmp_path / "ro") == []
    finally:
        (tmp_path / "ro").chmod(0o700)


def test_a_read_only_file_system_names_the_output_not_its_temporary_folder(
        tmp_path, monkeypatch, capsys):
    # a read-only mount read "error: Read-only file system: '.../ro/.rep.tmp-3yp6nw5k'",
    # the hidden folder the command builds in; it now names --out and what to do
    import errno
    import tempfile

    monkeypatch.chdir(tmp_path)
    (tmp_path / "data.csv").write_text(GOOD_CSV)

    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system",
                      os.path.join(kwargs.get("dir", "."), ".rep.tmp-x"))

    monkeypatch.setattr(tempfile, "mkdtemp", read_only)
    code = cli.main(["fit", "data.csv", "--sections", "1", "--out", "rep"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1
    assert err.startswith("error: cannot write the output folder 'rep': Read-only file system "
                          "in ") and "choose an output in a folder you can write to" in err
    assert ".tmp-" not in err


# ----------------------------------------------------------------------------- outputs


@pytest.fixture(scope="module")
def small_result():
    return fc.fit(fc.FrequencyData(W, RESP, "small"), n_sections=1)


@pytest.mark.parametrize("setup, out, match", [
    (lambda p: (p / "rep").mkdir(), "rep", "output folder 'rep' exists; pass --force"),
    (lambda p: (p / "rep").write_text("x"), "rep", "exists and is not a folder"),
    (lambda p: None, "nodir/rep", "parent folder .* does not exist"),
    (lambda p: (p / "afile").write_text("x"), "afile/rep", "parent folder .* does not exist"),
], ids=["exists", "is-a-file", "no-parent", "parent-is-a-file"])
def test_output_folder_that_cannot_be_used(small_result, tmp_path, monkeypatch, capsys,
                                           setup, out, match):
    monkeypatch.chdir(tmp_path)
    setup(tmp_path)
    before = _listing(tmp_path)
    with pytest.raises(OptionError, match=match):
        report.write_fit_report(small_result, out, command="test")
    assert _listing(tmp_path) == before
    fc.save_csv(small_result.data, tmp_path / "data.csv")
    before = _listing(tmp_path)
    code = cli.main(["fit", "data.csv", "--sections", "1", "--out", out])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and err.startswith("error: ")
    assert _listing(tmp_path) == before


def test_write_error_leaves_nothing(small_result, tmp_path, monkeypatch):
    def fail(*args):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(report, "_write_stages_csv", fail)
    with pytest.raises(OSError):
        report.write_fit_report(small_result, tmp_path / "rep", command="test")
    assert os.listdir(tmp_path) == []


def test_every_error_is_a_freqid_error_subclass_of_a_builtin():
    assert issubclass(DataError, ValueError) and issubclass(OptionError, ValueError)
    assert issubclass(StructureError, ValueError)
    assert issubclass(fc.SolverError, RuntimeError)


@pytest.mark.parametrize("make, what", [
    (lambda g: np.abs(g), r"is it a magnitude \|G\|\?"),
    (lambda g: 20 * np.log10(np.abs(g)) - 1.0, r"is it a level in dB\?"),
])
def test_a_real_response_of_one_sign_is_questioned_as_a_magnitude(make, what):
    # fit(omega, np.abs(G)) ran and ended poor-fit advising more sections, silently
    from freqid_casadi.io.loaders import DataWarning

    w = np.logspace(0, 2, 50)
    g = 1 / (1 + 1j * w / 10)
    with pytest.warns(DataWarning, match=r"the response is real at every point, of one sign "
                      rf"and not constant: {what} A frequency response needs its phase"):
        fc.fit(w, make(g), n_sections=1)
    # a constant real response is a gain, and undamped modes' real response changes sign:
    # no such warning
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        assert fc.fit(w, np.full(w.size, 2.5), n_sections=1).max_rel_error < 1e-6

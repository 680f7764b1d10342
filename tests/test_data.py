"""Tests of freqid_casadi.core.data: FrequencyData validation, windows and the file loaders."""

import dataclasses
import math
import os
import tempfile

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from freqid_casadi.core.data import FrequencyData
from freqid_casadi.io.loaders import load, load_csv, load_npz, save_csv
from freqid_casadi.errors import DataError, FreqidError

OMEGA = np.array([0.5, 1.0, 2.0, 4.0, 8.0])            # rad/s
RESP = np.array([1 + 1j, 2 - 1j, -1 + 0.5j, 0.25j, 3.0 + 0j])


def _with(arr, i, value, dtype=float):
    out = np.array(arr, dtype=dtype)
    out[i] = value
    return out


# ------------------------------------------------------------------ validation table
# (id, omega, response, weights, pattern): the pattern names the key phrase and the index.
BAD = [
    ("omega-nan", _with(OMEGA, 2, np.nan), RESP, None, r"omega must be finite: omega\[2\]=nan"),
    ("omega-inf", _with(OMEGA, 4, np.inf), RESP, None, r"omega must be finite: omega\[4\]=inf"),
    ("omega-neginf", _with(OMEGA, 0, -np.inf), RESP, None,
     r"omega must be finite: omega\[0\]=-inf"),
    ("response-nan", OMEGA, _with(RESP, 3, np.nan, complex), None,
     r"response must be finite: response\[3\]"),
    ("response-inf", OMEGA, _with(RESP, 1, complex(1, np.inf), complex), None,
     r"response must be finite: response\[1\]"),
    ("unsorted", OMEGA[[0, 1, 3, 2, 4]], RESP, None,
     r"strictly increasing value\): omega\[3\]=.* <= omega\[2\]=.*FrequencyData\.sorted"),
    ("duplicate", _with(OMEGA, 3, 2.0), RESP, None,
     r"duplicated value\): omega\[3\]=.* <= omega\[2\]="),
    ("omega-zero", _with(OMEGA, 0, 0.0), RESP, None, r"omega must be > 0 \(rad/s\): omega\[0\]=0"),
    ("omega-negative", np.array([-1.0, 1, 2, 3, 4]), RESP, None,
     r"omega must be > 0 \(rad/s\): omega\[0\]=-1"),
    ("length-mismatch", OMEGA, RESP[:4], None,
     r"equal lengths: len\(omega\)=5, len\(response\)=4"),
    ("empty", [], [], None, r"omega is empty"),
    ("zero-response", OMEGA, _with(RESP, 2, 0.0, complex), None,
     r"response must be nonzero.*response\[2\]=0"),
    ("complex-omega-list", [0.5, 1.0 + 1j, 2.0, 4.0, 8.0], RESP, None, r"omega must be real"),
    ("omega-2d", np.arange(1.0, 7.0).reshape(2, 3), np.ones((2, 3)), None,
     r"omega must be one-dimensional, got shape \(2, 3\)"),
    ("response-2d", np.arange(1.0, 7.0), np.ones((2, 3)), None,
     r"response must be one-dimensional, got shape \(2, 3\)"),
    ("omega-text", ["a", "b"], [1, 2], None, r"omega must be an array of numbers"),
    ("weights-negative", OMEGA, RESP, [1, -1, 1, 1, 1],
     r"weights must be finite and >= 0: weights\[1\]=-1"),
    ("weights-nan", OMEGA, RESP, [1, 1, 1, np.nan, 1],
     r"weights must be finite and >= 0: weights\[3\]=nan"),
    ("weights-inf", OMEGA, RESP, [1, 1, 1, 1, np.inf],
     r"weights must be finite and >= 0: weights\[4\]=inf"),
    ("weights-length", OMEGA, RESP, [1, 1, 1, 1],
     r"one value per frequency: len\(weights\)=4, len\(omega\)=5"),
    ("weights-all-zero", OMEGA, RESP, np.zeros(5), r"weights are all zero"),
    ("weights-complex", OMEGA, RESP, [1, 1j, 1, 1, 1], r"weights must be real"),
]


@pytest.mark.parametrize("omega, response, weights, pattern",
                         [pytest.param(*row[1:], id=row[0]) for row in BAD])
def test_invalid_data_raises(omega, response, weights, pattern):
    with pytest.raises(DataError, match=pattern):
        FrequencyData(omega, response, "bad", weights)


def test_complex_omega_ndarray_raises_data_error():
    with pytest.raises(DataError, match="omega must be real"):
        FrequencyData(OMEGA + 0.5j, RESP)


def test_unsorted_message_prints_plain_numbers():
    with pytest.raises(DataError, match=r"omega\[3\]=2\.0 <= omega\[2\]=4\.0"):
        FrequencyData(OMEGA[[0, 1, 3, 2, 4]], RESP)


def test_data_error_is_value_error():
    with pytest.raises(ValueError):
        FrequencyData([1.0, 1.0], [1.0, 1.0])
    assert issubclass(DataError, FreqidError)


def test_name_must_be_string():
    with pytest.raises(DataError, match="name must be a string or None, got int"):
        FrequencyData(OMEGA, RESP, 3)


# ------------------------------------------------------------------ valid data
def test_valid_data_round_trips_and_copies():
    omega, resp, w = OMEGA.copy(), RESP.copy(), np.array([1.0, 0.0, 2.0, 3.0, 0.5])
    data = FrequencyData(omega, resp, "plant", w)
    assert np.array_equal(data.omega, OMEGA) and data.omega.dtype == float
    assert np.array_equal(data.response, RESP) and data.response.dtype == complex
    assert np.array_equal(data.weights, w)
    assert data.name == "plant" and len(data) == data.n_points == 5
    omega[0] = 99.0                                     # the input is copied, not aliased
    resp[0] = 99.0
    w[0] = 99.0
    assert data.omega[0] == 0.5 and data.response[0] == 1 + 1j and data.weights[0] == 1.0


def test_real_response_and_lists_accepted():
    data = FrequencyData([1, 2, 3], [1, -2, 3])
    assert data.response.dtype == complex
    assert np.array_equal(data.response, [1, -2, 3])
    assert data.weights is None and data.name is None


def test_arrays_are_read_only_and_frozen():
    data = FrequencyData(OMEGA, RESP, weights=np.ones(5))
    for arr in (data.omega, data.response, data.weights):
        assert not arr.flags.writeable
        with pytest.raises(ValueError):
            arr[0] = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        data.omega = OMEGA


def test_with_weights():
    data = FrequencyData(OMEGA, RESP, "x")
    w = data.with_weights([1, 2, 3, 4, 5])
    assert np.array_equal(w.weights, [1, 2, 3, 4, 5]) and w.name == "x"
    assert w.with_weights(None).weights is None
    with pytest.raises(DataError, match=r"weights\[0\]=-2"):
        data.with_weights([-2, 1, 1, 1, 1])


# ------------------------------------------------------------------ windows
def test_window_keeps_lowest_frequencies():
    data = FrequencyData(OMEGA, RESP, "p", np.arange(1.0, 6.0))
    win = data.window(3)
    assert np.array_equal(win.omega, OMEGA[:3])
    assert np.array_equal(win.response, RESP[:3])
    assert np.array_equal(win.weights, [1.0, 2.0, 3.0])
    assert win.name == "p"
    assert np.array_equal(data.window(5).omega, OMEGA)
    assert data.window(1).n_points == 1


@pytest.mark.parametrize("n", [0, -1, 6, 100])
def test_window_bounds(n):
    data = FrequencyData(OMEGA, RESP)
    with pytest.raises(DataError, match=rf"window length must be in 1\.\.5, got {n}"):
        data.window(n)


# ------------------------------------------------------------------ sorted()
def test_sorted_sorts_and_drops_duplicates_keeping_first():
    omega = [4.0, 1.0, 2.0, 1.0, 8.0, 4.0]
    resp = [40, 10, 20, 11, 80, 41]
    weights = [4, 1, 2, 1.5, 8, 4.5]
    with pytest.warns(UserWarning, match="2 of them with a response that differs"):
        data = FrequencyData.sorted(omega, resp, "s", weights)
    assert np.array_equal(data.omega, [1.0, 2.0, 4.0, 8.0])
    assert np.array_equal(data.response, [10, 20, 40, 80])      # first occurrences kept
    assert np.array_equal(data.weights, [1, 2, 4, 8])
    assert data.name == "s"


def test_sorted_says_when_dropped_duplicates_differ():
    # the loader's error for duplicated rows points to FrequencyData.sorted; two sweeps in
    # one table give duplicates that differ (here 5x): kept the first, and said so
    import warnings

    from freqid_casadi.errors import DataWarning

    with pytest.warns(DataWarning, match=r"2 duplicated frequencies dropped, 1 of them with a "
                      r"response that differs from the one kept by more than 1 % \(up to 400 %, "
                      r"at omega 2\): the data may hold two sweeps"):
        d = FrequencyData.sorted([1.0, 2.0, 2.0, 3.0, 3.0], [1.0, 2.0, 10.0, 3.0, 3.001])
    np.testing.assert_array_equal(d.response, [1.0, 2.0, 3.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)      # equal duplicates: nothing to say
        FrequencyData.sorted([2.0, 1.0, 2.0], [2.0, 1.0, 2.0])
        with pytest.raises(DataError, match="response must be nonzero"):   # 0 and 0: equal
            FrequencyData.sorted([1.0, 1.0, 2.0], [0.0, 0.0, 1.0])


def test_sorted_still_validates():
    with pytest.raises(DataError, match=r"equal lengths"):
        FrequencyData.sorted([2.0, 1.0], [1.0])
    with pytest.raises(DataError, match=r"omega must be > 0.*omega\[0\]=-1"):
        FrequencyData.sorted([2.0, -1.0], [1.0, 1.0])


# ------------------------------------------------------------------ CSV loader
def _write(tmp_path, text, name="plant.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_csv_real_imag_layout(tmp_path):
    path = _write(tmp_path, "omega,real,imag\n1.0,2.0,-3.0\n2.5,0.5,4\n")
    data = load_csv(path)
    assert np.array_equal(data.omega, [1.0, 2.5])
    assert np.array_equal(data.response, [2 - 3j, 0.5 + 4j])
    assert data.name == "plant"
    assert load_csv(path, name="other").name == "other"
    assert np.array_equal(load(path).response, data.response)       # dispatch by extension


def test_csv_magnitude_phase_layout(tmp_path):
    # 3 - 4j: |G| = 5, so 20 log10(5) dB, and phase atan2(-4, 3) in degrees.
    g = 3 - 4j
    db, deg = 20 * math.log10(abs(g)), math.degrees(math.atan2(g.imag, g.real))
    path = _write(tmp_path, f"omega,magnitude_db,phase_deg\n1.0,{db!r},{deg!r}\n"
                            "2.0,20,90\n3.0,-6.020599913279624,180\n")
    data = load_csv(path)
    assert data.response[0] == pytest.approx(g, rel=1e-14)
    assert data.response[1] == pytest.approx(10j, rel=1e-14)          # 20 dB, +90 deg
    assert data.response[2] == pytest.approx(-0.5, rel=1e-12)         # -6.02 dB, 180 deg


def test_csv_header_case_spaces_comments_blank_lines(tmp_path):
    text = ("# measured 2024-01-01, rig A\n"
            "\n"
            " Omega , REAL , Imag \n"
            "# a comment between rows, with, commas\n"
            "1, 1, 1\n"
            "\n"
            "2, 2, 2\n")
    data = load_csv(_write(tmp_path, text))
    assert np.array_equal(data.omega, [1.0, 2.0])
    assert np.array_equal(data.response, [1 + 1j, 2 + 2j])


@pytest.mark.parametrize("text, pattern", [
    pytest.param("x,re,im\n1,2,3\n", r"unrecognised header 'x,re,im'.*omega,real,imag",
                 id="bad-header"),
    pytest.param("omega,real\n1,2\n", r"unrecognised header 'omega,real'", id="header-2-cols"),
    pytest.param("omega,real,extra,more\n1,2,3,4\n", r"unrecognised header",
                 id="header-4-cols"),
    pytest.param("omega,real,imag\n1,2,3\n2,3\n",
                 r"line 3: expected 3 columns \(omega,real,imag\), got 2", id="missing-column"),
    pytest.param("omega,real,imag\n1,2,3,4\n", r"line 2: expected 3 columns.*got 4",
                 id="extra-column"),
    pytest.param("omega,real,imag\n1,2,3\n2,abc,4\n",
                 r"line 3, column 'real': 'abc' is not a number", id="non-numeric"),
    pytest.param("omega,magnitude_db,phase_deg\n1,2,3\n2,4, \n",
                 r"line 3, column 'phase_deg': '' is not a number", id="empty-cell"),
    pytest.param("", r"is empty", id="empty-file"),
    pytest.param("# only a comment\n\n", r"is empty", id="comments-only"),
    pytest.param("omega,real,imag\n", r"has a header but no data rows", id="header-only"),
    # (two rows in descending order are a descending file, reversed with a DataWarning)
    pytest.param("omega,real,imag\n1,1,1\n3,1,1\n2,1,1\n",
                 r"line 4, column .omega.: the frequencies must be strictly increasing.*"
                 r"2\.0 after 3\.0 on line 3",
                 id="unsorted-rows"),
    pytest.param("omega,real,imag\n1,0,0\n", r"response must be nonzero.*response\[0\]",
                 id="zero-response"),
])
def test_csv_errors(tmp_path, text, pattern):
    with pytest.raises(DataError, match=pattern):
        load_csv(_write(tmp_path, text))


def test_csv_error_line_counts_comments(tmp_path):
    text = "# comment\n\nomega,real,imag\n1,2,3\n2,x,4\n"             # bad cell on line 5
    with pytest.raises(DataError, match=r"line 5, column 'real'"):
        load_csv(_write(tmp_path, text))


def test_csv_missing_file_and_directory(tmp_path):
    with pytest.raises(DataError, match=r"data file not found: .*nope\.csv"):
        load_csv(tmp_path / "nope.csv")
    with pytest.raises(DataError, match=r"is a directory, not a data file"):
        load_csv(tmp_path)
    with pytest.raises(DataError, match=r"data file not found"):
        load(tmp_path / "nope.npz")


def test_csv_not_utf8(tmp_path):
    path = tmp_path / "bin.csv"
    path.write_bytes(b"\xff\xfe\x00\x01omega")
    with pytest.raises(DataError, match=r"not a text CSV file"):
        load_csv(path)


# ------------------------------------------------------------------ NPZ loader
def test_npz_good_file(tmp_path):
    path = tmp_path / "meas.npz"
    np.savez(path, omega=OMEGA, response=RESP)
    data = load_npz(path)
    assert np.array_equal(data.omega, OMEGA) and np.array_equal(data.response, RESP)
    assert data.weights is None and data.name == "meas"
    assert np.array_equal(load(path).response, RESP)                  # dispatch by extension
    assert load_npz(path, name="n").name == "n"


def test_npz_with_weights(tmp_path):
    path = tmp_path / "w.npz"
    np.savez(path, omega=OMEGA, response=RESP, weights=np.arange(5.0))
    assert np.array_equal(load_npz(path).weights, np.arange(5.0))
    np.savez(path, omega=OMEGA, response=RESP, weights=-np.ones(5))
    with pytest.raises(DataError, match=r"weights\[0\]=-1"):
        load_npz(path)


@pytest.mark.parametrize("arrays, missing", [
    ({"omega": OMEGA}, r"\['response'\]"),
    ({"response": RESP}, r"\['omega'\]"),
])
def test_npz_missing_arrays(tmp_path, arrays, missing):
    path = tmp_path / "m.npz"
    np.savez(path, **arrays)
    with pytest.raises(DataError, match=rf"lacks array\(s\) {missing}.*np\.savez"):
        load_npz(path)


def test_npz_of_other_names_is_read_by_the_text_vocabulary(tmp_path):
    # w (rad/s) and g (complex): the names a headerless table's header may use
    path = tmp_path / "m.npz"
    np.savez(path, w=OMEGA, g=RESP)
    data = load_npz(path)
    assert np.array_equal(data.omega, OMEGA) and np.array_equal(data.response, RESP)
    np.savez(path, a=OMEGA, b=OMEGA)          # nothing to tell them by
    with pytest.raises(DataError, match=r"cannot tell the variables apart \(found a \(5\), "
                       r"b \(5\)\).*np\.savez"):
        load_npz(path)


def test_npz_invalid_content(tmp_path):
    path = tmp_path / "bad.npz"
    shuffled = OMEGA.copy()
    shuffled[[1, 2]] = shuffled[[2, 1]]      # (a descending grid is reversed, with a warning)
    np.savez(path, omega=shuffled, response=RESP)
    with pytest.raises(DataError, match=r"strictly increasing"):
        load_npz(path)
    path.write_text("not a zip file")
    with pytest.raises(DataError, match=r"cannot read .* as \.npz"):
        load_npz(path)


def test_npz_that_is_really_npy(tmp_path):
    path = tmp_path / "arr.npy"
    np.save(path, OMEGA)
    target = tmp_path / "arr.npz"
    os.replace(path, target)
    with pytest.raises(DataError):
        load_npz(target)


# ------------------------------------------------------------------ save_csv round trip
AWKWARD = np.array([1 / 3, 0.1, 2.0 ** 0.5, math.pi, 1e300, 1e-300, 12345.678901234567])


def test_save_csv_round_trip_bit_exact(tmp_path):
    omega = np.sort(AWKWARD)
    resp = np.array([complex(1 / 7, -1e-17), complex(-2.5e200, 3e-310), complex(1, 1 / 3),
                     complex(-math.e, 0.0), complex(5e-324, 1e308), 1j, -0.1 + 0.2j])
    data = FrequencyData(omega, resp, "rt")
    path = tmp_path / "rt.csv"
    save_csv(data, path)
    assert path.read_text().splitlines()[0] == "omega,real,imag"
    back = load_csv(path)
    assert back.omega.tobytes() == data.omega.tobytes()
    assert back.response.tobytes() == data.response.tobytes()
    assert back.name == "rt"
    assert not any(p.name.startswith(".tmp-") for p in tmp_path.iterdir())   # atomic write


def test_save_csv_round_trip_signed_zero(tmp_path):
    data = FrequencyData([1.0, 2.0], [complex(1.0, -0.0), complex(-0.0, 1.0)])
    save_csv(data, tmp_path / "z.csv")
    back = load_csv(tmp_path / "z.csv")
    assert back.response.tobytes() == data.response.tobytes()


_finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
_omegas = st.lists(st.floats(min_value=1e-12, max_value=1e12, allow_nan=False,
                             allow_infinity=False, exclude_min=True),
                   min_size=1, max_size=25, unique=True).map(sorted)


@st.composite
def _data(draw):
    omega = draw(_omegas)
    pair = st.tuples(_finite, _finite).filter(lambda p: p != (0.0, 0.0))
    resp = [complex(*draw(pair)) for _ in omega]
    return np.array(omega), np.array(resp, dtype=complex)


@settings(max_examples=50, deadline=None)
@given(_data())
def test_property_valid_data_constructs_and_round_trips(arrays):
    omega, resp = arrays
    data = FrequencyData(omega, resp)
    assert np.array_equal(data.omega, omega) and np.array_equal(data.response, resp)
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "prop.csv")
        save_csv(data, path)
        back = load_csv(path)
    # exact in value (== treats -0.0 as 0.0; signed zeros have their own test)
    assert np.array_equal(back.omega, data.omega)
    assert np.array_equal(back.response.real, data.response.real)
    assert np.array_equal(back.response.imag, data.response.imag)


def test_repr_summarises_instead_of_printing_every_sample():
    d = FrequencyData(np.geomspace(1.0, 1000.0, 400), np.full(400, 2.0 + 0j), "plant")
    text = repr(d)
    assert text == ("FrequencyData(name='plant', 400 points, omega 1 to 1000 rad/s, "
                    "|response| 2 to 2)")
    assert len(text) < 120 and str(d) == text

"""A ``.mat`` file whose frequency axis is given by scalars beside the response: a start and
a step (``f_start``/``df``, ``f0``/``df``, ``fstart``/``fstep``, ``freq_start``/``delta_f``),
or a start and an end, the count from the response's length; and the message for a file
whose response has no frequency axis at all.

The files are written as MATLAB writes them (``save(..., '-v7')``, through scipy.io).
"""

import warnings

import numpy as np
import pytest
import scipy.io

import freqid_casadi as fc
from freqid_casadi.errors import DataError
from freqid_casadi.io.loaders import DataWarning

H = np.array([2 - 1j, 1 - 0.5j, 0.25 + 0.5j, 0.1 + 0.2j])


def _mat(tmp_path, name="frf.mat", **variables):
    path = tmp_path / name
    scipy.io.savemat(str(path), variables)
    return path


@pytest.mark.parametrize("start, step", [("f_start", "df"), ("f0", "df"),
                                         ("fstart", "fstep"), ("freq_start", "delta_f")])
def test_start_and_step_give_the_axis(tmp_path, start, step):
    path = _mat(tmp_path, frf=H, **{start: 10.0, step: 2.5})
    data = fc.load(path, freq_unit="Hz")
    np.testing.assert_allclose(data.omega, 2 * np.pi * np.array([10.0, 12.5, 15.0, 17.5]),
                               rtol=1e-15)
    np.testing.assert_array_equal(data.response, H)
    assert data.response[2] == 0.25 + 0.5j          # at 15 Hz
    # in rad/s when freq_unit says so
    np.testing.assert_allclose(fc.load(path, freq_unit="rad/s").omega,
                               [10.0, 12.5, 15.0, 17.5], rtol=1e-15)


def test_the_unit_of_f_start_is_asked_for_unless_a_name_says_it(tmp_path):
    path = _mat(tmp_path, frf=H, f_start=10.0, df=2.5)
    with pytest.raises(DataError, match=r"the frequency unit of f_start = 10, df = 2\.5 is "
                       r"unknown: pass freq_unit='Hz' or freq_unit='rad/s' \(command line "
                       r"--freq-unit hz\|rad/s\)"):
        fc.load(path)
    hz = _mat(tmp_path, "hz.mat", response=H, f_start_hz=1.0, df_hz=1.0)
    np.testing.assert_allclose(fc.load(hz).omega, 2 * np.pi * np.arange(1.0, 5.0),
                               rtol=1e-15)
    rad = _mat(tmp_path, "rad.mat", response=H, w0=0.5, dw=0.25)
    np.testing.assert_allclose(fc.load(rad).omega, [0.5, 0.75, 1.0, 1.25], rtol=1e-15)
    with pytest.raises(DataError, match=r"freq_unit='hz' contradicts w0 = 0\.5, dw = 0\.25 "
                       r"\(rad/s\)"):
        fc.load(rad, freq_unit="Hz")


def test_an_end_or_a_count_beside_the_step_is_checked(tmp_path):
    # fend is the last point, or one step beyond it, or the last bin's edge: all within a
    # step of the axis's last point
    for fend in (4.0, 5.0, 4.5):
        path = _mat(tmp_path, frf=H, fstart=1.0, fstep=1.0, fend=fend, nf=4.0)
        np.testing.assert_allclose(fc.load(path, freq_unit="Hz").omega,
                                   2 * np.pi * np.arange(1.0, 5.0), rtol=1e-15)
    path = _mat(tmp_path, frf=H, fstart=1.0, fstep=1.0, fend=9.0)
    with pytest.raises(DataError, match=r"fstart \+ k\*fstep over the response's 4 points "
                       r"ends at 4, more than one step from fend = 9: the response and the "
                       r"axis are not of one sweep"):
        fc.load(path, freq_unit="Hz")
    path = _mat(tmp_path, frf=H, fstart=1.0, fstep=1.0, n_points=5.0)
    with pytest.raises(DataError, match=r"n_points = 5 points, but the response has 4"):
        fc.load(path, freq_unit="Hz")


def test_start_and_end_without_a_step(tmp_path):
    path = _mat(tmp_path, frf=H, fstart=100.0, fend=400.0)
    np.testing.assert_allclose(fc.load(path, freq_unit="Hz").omega,
                               2 * np.pi * np.array([100.0, 200.0, 300.0, 400.0]), rtol=1e-15)


def test_fields_of_a_struct(tmp_path):
    path = _mat(tmp_path, meas={"frf": H, "f_start_hz": 5.0, "df_hz": 5.0})
    data = fc.load(path)
    np.testing.assert_allclose(data.omega, 2 * np.pi * np.array([5.0, 10.0, 15.0, 20.0]),
                               rtol=1e-15)
    np.testing.assert_array_equal(data.response, H)


def test_an_unnamed_two_column_matrix_beside_the_axis_is_real_and_imaginary(tmp_path):
    # a modal test's FRF saved as H00 (N x 2: real, imaginary) with f_start (uint8 0),
    # df and f_end, as a published data set holds it; the DC row is dropped with a note
    mat = np.column_stack([H.real, H.imag])
    path = _mat(tmp_path, "H00.mat", H00=mat, df=0.5, f_end=1.5, f_start=np.uint8(0))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        data = fc.load(path, freq_unit="Hz")
    notes = [str(w.message) for w in caught if issubclass(w.category, DataWarning)]
    assert any("read the two columns of H00 (4 x 2) as the real and imaginary parts" in n
               for n in notes)
    assert any("dropped 1 row(s) at zero frequency" in n for n in notes)
    np.testing.assert_allclose(data.omega, 2 * np.pi * np.array([0.5, 1.0, 1.5]), rtol=1e-15)
    np.testing.assert_array_equal(data.response, H[1:])
    assert data.response[0] == 1 - 0.5j               # at 0.5 Hz
    # an unnamed complex vector is the response, without a note
    vec = _mat(tmp_path, "vec.mat", Txy1=H, df=0.5, f_start=0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        np.testing.assert_array_equal(fc.load(vec, freq_unit="Hz").response, H)


def test_two_arrays_beside_the_axis_are_named(tmp_path):
    mat = np.column_stack([H.real, H.imag])
    path = _mat(tmp_path, "H2.mat", H21=mat, H22=2 * mat, df=1.0, f_end=3.0, f_start=0.0)
    with pytest.raises(DataError, match=r"gives a frequency axis \(df, f_end, f_start\) "
                       r"beside 2 other arrays, not one response \(found H21 \(4 x 2\), H22 "
                       r"\(4 x 2\), df \(scalar\), f_end \(scalar\), f_start \(scalar\)\): "
                       r"choose the response with parameter='H21'"):
        fc.load(path, freq_unit="Hz")


def test_part_of_an_axis_says_what_is_missing(tmp_path):
    path = _mat(tmp_path, frf=H, freq_start=1.0)
    with pytest.raises(DataError, match=r"gives part of a frequency axis \(freq_start = 1\) "
                       r"but not its step \(df, fstep, delta_f\) or its end"):
        fc.load(path, freq_unit="Hz")
    path = _mat(tmp_path, frf=H, df=1.0)
    with pytest.raises(DataError, match=r"\(df = 1\) but not its start \(f_start, f0, fstart, "
                       r"freq_start; 0 when the first point is DC\)"):
        fc.load(path, freq_unit="Hz")
    path = _mat(tmp_path, frf=H, f_start=1.0, df=-1.0)
    with pytest.raises(DataError, match=r"the frequency step df = -1 must be positive"):
        fc.load(path, freq_unit="Hz")


def test_a_response_without_any_axis_lists_the_variables_and_what_to_save(tmp_path):
    path = _mat(tmp_path, frf=H, fs=100.0, nfft=8.0)
    with pytest.raises(DataError, match=r"holds a response \(frf\) but no frequency axis "
                       r"\(found frf \(4, complex\), fs \(scalar\), nfft \(scalar\)\): save "
                       r"the frequencies beside it as freq_hz \(Hz\) or omega \(rad/s\).*or "
                       r"their start and step as scalars f_start and df .*or build the data "
                       r"in Python: freqid_casadi\.FrequencyData\(omega, response\)"):
        fc.load(path)


# -- several responses in one file: parameter= chooses one --------------------------------

def test_parameter_chooses_one_of_several_responses_beside_one_axis(tmp_path):
    # a modal test's file: two FRFs as real N x 2 matrices (real, imaginary) beside the
    # scalars of the axis
    h21 = np.column_stack([H.real, H.imag])
    path = _mat(tmp_path, "H2.mat", H21=h21, H22=2 * h21, f_start=10.0, df=2.5)
    with pytest.raises(DataError, match=r"parameter='H21' \(command line --parameter H21\)"):
        fc.load(path, freq_unit="Hz")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        data = fc.load(path, freq_unit="Hz", parameter="H22")
    np.testing.assert_array_equal(data.response, 2 * H)
    np.testing.assert_allclose(data.omega / (2 * np.pi), [10.0, 12.5, 15.0, 17.5], rtol=1e-15)
    with pytest.raises(DataError, match="no variable 'H2'; its arrays: H21, H22"):
        fc.load(path, freq_unit="Hz", parameter="H2")
    with pytest.raises(DataError, match="df .*is not a response"):
        fc.load(path, freq_unit="Hz", parameter="df")


def test_parameter_chooses_a_complex_response_beside_a_frequency_vector(tmp_path):
    path = _mat(tmp_path, freq_hz=np.array([1.0, 2.0, 4.0, 8.0]), H11=H, H21=1j * H)
    data = fc.load(path, parameter="H21")
    np.testing.assert_array_equal(data.response, 1j * H)
    np.testing.assert_allclose(data.omega, 2 * np.pi * np.array([1.0, 2.0, 4.0, 8.0]),
                               rtol=1e-15)

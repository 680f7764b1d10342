"""Tests of freqid_casadi.plots: figures are returned (never shown) and saved atomically."""

import os

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from freqid_casadi import plots  # noqa: E402
from freqid_casadi.core.data import FrequencyData  # noqa: E402
from freqid_casadi.errors import OptionError  # noqa: E402
from freqid_casadi.fitting.fit import fit  # noqa: E402
from freqid_casadi.core.model import RationalDelayModel, Structure  # noqa: E402

# a known 2-section model with integrator and delay, 60 points (fits in about a second)
_BETA = [0.01, 4.0, 1, 0.05, 3.0, 1, 0.02, 2.0, 1, 0.03, 30.0, 1, 0.01, 20.0]


@pytest.fixture(scope="module")
def true_model():
    return RationalDelayModel(Structure(2, integrator=True), np.array(_BETA))


@pytest.fixture(scope="module")
def data(true_model):
    omega = np.logspace(-1, 2, 60)
    return FrequencyData(omega, true_model.frequency_response(omega), "plant")


@pytest.fixture(scope="module")
def result(data):
    return fit(data, n_sections=2, integrator=True)


@pytest.fixture(autouse=True)
def mplcleanup():
    yield
    plt.close("all")


def _texts(fig):
    out = []
    for ax in fig.axes:
        out += [ax.get_xlabel(), ax.get_ylabel(), ax.get_title()]
    if fig._suptitle is not None:
        out.append(fig._suptitle.get_text())
    return " ".join(out)


def test_bode_of_result(result):
    fig = plots.bode(result)
    assert isinstance(fig, Figure)
    assert len(fig.axes) == 2
    text = _texts(fig)
    for unit in ("dB", "degrees", "rad/s"):
        assert unit in text
    ax_mag, ax_ph = fig.axes
    assert ax_mag.get_xscale() == "log"
    # the data markers lie on the model line (the fit is exact), phase on the same branch
    model_line, data_line = ax_ph.get_lines()[0], ax_ph.get_lines()[-1]
    w_model, ph_model = model_line.get_data()
    w_data, ph_data = data_line.get_data()
    np.testing.assert_allclose(np.interp(w_data, w_model, ph_model), ph_data, atol=1e-6)
    # the delay is included: the phase at 100 rad/s is below the delay-free phase
    g = result.model.rational_response(np.array([100.0]))
    assert ph_model[-1] < np.rad2deg(np.angle(g[0])) - 50


def test_bode_of_data_and_models(data, true_model):
    fig = plots.bode(data)
    assert len(fig.axes[0].get_lines()) == 1
    fig = plots.bode(data, {"truth": true_model, "other": true_model})
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels[:2] == ["truth", "other"]


def test_bode_bad_input(data):
    with pytest.raises(OptionError, match="FitResult or a FrequencyData"):
        plots.bode(np.ones(3))
    with pytest.raises(OptionError, match="RationalDelayModel or FitResult"):
        plots.bode(data, [1.0])


def test_relative_error_several_results(result):
    fig = plots.relative_error({"ipopt": result, "again": result}, reference=0.2549,
                               reference_label="thesis")
    ax = fig.axes[0]
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
    assert "rad/s" in ax.get_xlabel()
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[:2] == ["ipopt", "again"] and labels[2].startswith("thesis")
    notes = [t.get_text() for t in ax.texts]
    assert any(f"max {result.max_rel_error:.3g}" in n for n in notes)
    with pytest.raises(OptionError, match="labels has 1 entries"):
        plots.relative_error([result, result], labels=["one"])


def test_relative_error_between_the_samples(result, true_model):
    """With the true system, a thin curve on a 10x denser grid: its data are the errors
    there, and the legend states their max."""
    fig = plots.relative_error(result, truth=true_model.frequency_response)
    ax = fig.axes[0]
    dense = [ln for ln in ax.get_lines() if "between the samples" in ln.get_label()]
    assert len(dense) == 1
    w, e = dense[0].get_data()
    assert w.size == 10 * result.data.n_points
    expected = np.abs(true_model.frequency_response(w) / result.model.frequency_response(w) - 1)
    np.testing.assert_allclose(e, expected, rtol=1e-12, atol=0)
    assert f"max {np.max(expected):.3g}" in dense[0].get_label()


def test_pole_zero(result, true_model):
    fig = plots.pole_zero(result.model)
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    poles_line = ax.get_lines()[2]                     # after the two axis lines
    assert poles_line.get_marker() == "x"
    np.testing.assert_allclose(np.sort_complex(poles_line.get_xdata()
                                               + 1j * poles_line.get_ydata()),
                               np.sort_complex(true_model.poles()[1:]), rtol=1e-6)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "integrator pole" in labels
    fig = plots.pole_zero(result.model, zoom=5.0)
    assert len(fig.axes) == 2
    lo, hi = fig.axes[1].get_ylim()
    assert lo == -hi and 5.0 <= hi < 6.0
    assert len(plots.pole_zero(result, zoom="auto").axes) == 2
    with pytest.raises(OptionError, match="zoom"):
        plots.pole_zero(result.model, zoom=-1)
    with pytest.raises(OptionError, match="zoom"):
        plots.pole_zero(result.model, zoom="big")


def test_stage_errors(result):
    fig = plots.stage_errors({"a": result, "b": result}, window=True)
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    x, y = ax.get_lines()[0].get_data()
    assert list(x) == [s.stage for s in result.stages]
    np.testing.assert_allclose(y, [s.max_rel_error for s in result.stages])


def test_save_figure_writes_png_and_closes(result, tmp_path):
    fig = plots.bode(result)
    num = fig.number
    path = plots.save_figure(fig, tmp_path / "bode.png")
    assert os.path.getsize(path) > 1000
    with open(path, "rb") as fh:
        assert fh.read(8) == b"\x89PNG\r\n\x1a\n"
    assert not plt.fignum_exists(num)
    assert os.listdir(tmp_path) == ["bode.png"]          # no temporary file left


def test_save_figure_failure_leaves_nothing(result, tmp_path):
    fig = plots.relative_error(result)
    with pytest.raises(ValueError):
        plots.save_figure(fig, tmp_path / "x.notaformat")
    assert os.listdir(tmp_path) == []
    assert not plt.fignum_exists(fig.number)


def test_missing_matplotlib_is_a_clear_import_error(monkeypatch, result):
    monkeypatch.setitem(__import__("sys").modules, "matplotlib.pyplot", None)
    with pytest.raises(ImportError, match="pip install matplotlib"):
        plots.bode(result)
    with pytest.raises(plots.MatplotlibMissingError):
        plots.pole_zero(result.model)


def test_bode_curves_put_every_phase_on_the_reference_branch():
    # noisy data near -180 deg wrap between +-180; a model's own unwrap starts at +180:
    # both must be drawn on one branch (the robot arm's figure had them 360 deg apart)
    from freqid_casadi import plots

    w = np.logspace(-2, 0, 50)
    model = -1.0 / (1 + 1j * w)                          # phase 180 -> 135 deg
    rng = np.random.default_rng(0)
    data = model * np.exp(1j * 0.02 * rng.standard_normal(w.size))
    data[0] = -abs(data[0]) * np.exp(-0.01j)             # first point just below -180
    fig = plots.bode_curves(w, {"model": model}, reference=("data", data),
                            xlabel="omega (rad/sample)")
    ax_p = fig.axes[1]
    ref, mod = (line.get_ydata() for line in ax_p.get_lines()[:2])
    assert np.all(np.abs(np.diff(ref)) < 180)            # the data unwrapped
    assert np.max(np.abs(mod - ref)) < 10                # the model on the data's branch
    assert ax_p.get_xlabel() == "omega (rad/sample)"
    plt.close(fig)


def test_fit_figures_label_their_frequency_unit(result):
    # the robot arm's figures (normalised frequency) were labelled rad/s
    from freqid_casadi import plots

    figs = [plots.bode(result, unit="rad/sample"),
            plots.relative_error(result, unit="rad/sample"),
            plots.pole_zero(result, unit="rad/sample")]
    labels = [ax.get_xlabel() for fig in figs for ax in fig.axes]
    assert labels and all("rad/sample" in lab for lab in labels if lab)
    assert not any("rad/s)" in lab for lab in labels)
    assert "rad/s)" in plots.bode(result).axes[1].get_xlabel()      # the default
    for fig in figs:
        plt.close(fig)
    plt.close("all")

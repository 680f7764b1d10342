"""scikit-rf's vector fitting as an outside peer (layer L4; the ``[peers]`` extra).

The package's own :func:`~freqid_casadi.baselines.vector_fitting` is a re-implementation;
comparing with scikit-rf's ``VectorFitting`` (the tool users of vector fitting have) keeps
the comparison honest. scikit-rf is imported inside the function: it is not a core
dependency (``pip install freqid_casadi[peers]``).
"""

import warnings

import numpy as np

from ..core.data import FrequencyData
from ..errors import DataError, OptionError
from ._ssmodel import pole_residue_ss

__all__ = ["skrf_vector_fitting"]


def skrf_vector_fitting(data, n_poles, *, fit_constant=True):
    """scikit-rf vector fitting of a SISO frequency response with ``n_poles`` poles.

    Parameters
    ----------
    data : FrequencyData
        Samples ``response = G(j omega)``, omega in rad/s (given to scikit-rf in Hz).
    n_poles : int
        Model order: ``n_poles // 2`` complex pairs and ``n_poles % 2`` real poles
        (scikit-rf's ``n_poles_cmplx``, ``n_poles_real``), initial poles spaced
        logarithmically.
    fit_constant : bool
        Fit a constant term (scikit-rf's default).

    Returns
    -------
    StateSpaceModel
        ``name = "skrf-vector-fitting"``; stability and minimum phase are whatever
        scikit-rf returns (its poles are flipped stable, zeros are free).

    Raises
    ------
    OptionError
        scikit-rf is not installed (``pip install freqid_casadi[peers]``).
    """
    if not isinstance(data, FrequencyData):
        raise DataError(f"data must be a FrequencyData, got {type(data).__name__}")
    if isinstance(n_poles, bool) or not isinstance(n_poles, (int, np.integer)) or n_poles < 1:
        raise OptionError(f"n_poles must be a positive integer, got {n_poles!r}")
    try:
        import skrf
        from skrf.vectorFitting import VectorFitting
    except ImportError:
        raise OptionError("scikit-rf is not installed: pip install 'freqid_casadi[peers]'"
                          ) from None
    freq = skrf.Frequency.from_f(data.omega / (2 * np.pi), unit="hz")
    ntw = skrf.Network(frequency=freq, s=np.asarray(data.response, complex).reshape(-1, 1, 1))
    vf = VectorFitting(ntw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        vf.vector_fit(n_poles_real=int(n_poles) % 2, n_poles_cmplx=int(n_poles) // 2,
                      init_pole_spacing="log", fit_constant=fit_constant,
                      fit_proportional=False)
    poles = np.asarray(vf.poles, complex)
    res = np.asarray(vf.residues, complex).reshape(-1)
    real = np.abs(poles.imag) == 0
    d = float(np.real(np.asarray(vf.constant_coeff).reshape(-1)[0])) if fit_constant else 0.0
    return pole_residue_ss(poles[real].real, res[real].real, poles[~real], res[~real], d,
                           "skrf-vector-fitting")

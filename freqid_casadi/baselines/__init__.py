"""Baseline methods the thesis compares against, and peers (layer L4; SPEC §6).

Every method is a function returning a :class:`StateSpaceModel`, which has the interface of
:class:`~freqid_casadi.core.model.RationalDelayModel` (``frequency_response``, ``poles``,
``zeros``, ``is_stable``, ``is_minimum_phase``, ``to_control``, ``order``, ``delay``,
``name``):

- :func:`subspace` — McKelvey, Akçay & Ljung (1996), frequency-domain subspace method;
- :func:`fourier` — Gu, Khargonekar & Lee (1989), FFT + FIR + balanced truncation;
- :func:`continued_fraction_sqrt`, :func:`newton_sqrt` — 1/sqrt(s) by Matsuda & Fujii's
  continued fraction and Carlson & Halijak's regular Newton process;
- :func:`balanced_truncation`, :func:`hankel_singular_values` — SLICOT via slycot;
- :func:`moheimani_kopt`, :func:`feedthrough_from_data` — Moheimani's feedthrough;
- :func:`aaa`, :func:`vector_fitting` — unconstrained peers; :func:`count_rhp`;
- :func:`vectfit` — the one vector fitting: C >= 1 channels with common poles (one channel
  is :func:`vector_fitting`, many the rational start of ``fit_shared``), with
  :class:`VectorFit`, :func:`fit_residues`, :func:`initial_poles`;
- :func:`skrf_vector_fitting` — scikit-rf's vector fitting (the ``[peers]`` extra).

python-control is imported inside the functions that need it, so importing this package
does not load matplotlib.
"""

from ._ssmodel import StateSpaceModel, count_rhp
from .balanced import balanced_truncation, balanced_truncation_error_bound, hankel_singular_values
from .feedthrough import feedthrough_from_data, modal_model, moheimani_kopt
from .fourier import fourier, fourier_impulse_response, interpolate_response
from .fractional import (continued_fraction_sqrt, newton_sqrt, newton_sqrt_polynomials,
                         thiele_coefficients)
from .peers import aaa, vector_fitting
from .skrf_peer import skrf_vector_fitting
from .subspace import default_bilinear_T, subspace
from .vectfit import VectorFit, fit_residues, initial_poles, vectfit

__all__ = [
    "StateSpaceModel", "count_rhp",
    "subspace", "default_bilinear_T",
    "fourier", "fourier_impulse_response", "interpolate_response",
    "balanced_truncation", "hankel_singular_values", "balanced_truncation_error_bound",
    "moheimani_kopt", "feedthrough_from_data", "modal_model",
    "continued_fraction_sqrt", "newton_sqrt", "newton_sqrt_polynomials", "thiele_coefficients",
    "aaa", "vector_fitting", "skrf_vector_fitting",
    "vectfit", "VectorFit", "fit_residues", "initial_poles",
]

"""Balanced truncation and Hankel singular values of a model's rational part (layer L4).

Used to show how far an identified order can be reduced (thesis figs 4.5, 4.11, 4.16;
SPEC §6). The Gramians and the balancing are SLICOT's (AB09AD / AB09MD through slycot and
python-control), never re-derived here (docs/style.md §2).
"""

import numpy as np

from ..errors import DataError
from ._ssmodel import StateSpaceModel, ab09ad, as_abcd, check_order

__all__ = ["balanced_truncation", "hankel_singular_values", "balanced_truncation_error_bound"]


def _split_unstable(A):
    return bool(A.shape[0]) and bool(np.any(np.linalg.eigvals(A).real >= 0))


def hankel_singular_values(model):
    """Hankel singular values of the rational part of a model, decreasing.

    Parameters
    ----------
    model : StateSpaceModel, RationalDelayModel or control.StateSpace
        SISO, continuous time. The delay is ignored (it does not change the rational
        part). A RationalDelayModel is converted with ``to_control()``.

    Returns
    -------
    ndarray of float, shape (n_s,)
        The HSVs of the stable part, ``n_s`` its order. Poles with ``Re >= 0`` (an
        integrator, unstable poles) are split off first and have no HSV
        (SLICOT AB09MD with boundary alpha = 0); for a stable model ``n_s = n``.

    Notes
    -----
    SLICOT AB09AD/AB09MD compute the HSVs by the square-root method from Cholesky
    factors of the Gramians, which is accurate for the small HSVs that python-control's
    ``hsvd`` (eigenvalues of ``Wo Wc``) loses.
    """
    A, B, C, D, _, _ = as_abcd(model)
    n = A.shape[0]
    if n == 0:
        return np.zeros(0)
    if _split_unstable(A):
        from slycot import ab09md

        out = ab09md("C", "B", "N", n, 1, 1, np.array(A, float), np.array(B, float),
                     np.array(C, float), alpha=0.0, nr=n, tol=0.0)
        ns, hsv = out[4], out[5]
        return np.asarray(hsv[:ns], float)
    return ab09ad(A, B, C, n, "C")[3]


def balanced_truncation(model, order):
    """Balanced truncation of the rational part to ``order`` states (delay kept).

    Parameters
    ----------
    model : StateSpaceModel, RationalDelayModel or control.StateSpace
        SISO, continuous time; a RationalDelayModel goes through ``to_control()``.
    order : int
        Requested order r >= 1 (SLICOT returns at most the minimal order).

    Returns
    -------
    StateSpaceModel
        ``name = "<input name> balanced(r)"``, with the input's delay and D.

    Raises
    ------
    DataError
        If the model has more poles with Re >= 0 than ``order``.

    Notes
    -----
    Stable models: SLICOT AB09AD (square-root balance & truncate), as python-control's
    ``balred(method="truncate")`` calls it, so that the Hankel singular values of the same
    call give the error bound (:func:`balanced_truncation_error_bound`):
    ``||G - G_r||_inf <= 2 sum_{i > r} sigma_i``. Models with poles at or right of the
    imaginary axis go to python-control's ``balred`` (SLICOT AB09MD): the unstable part
    is kept exactly and only the stable part is reduced.
    """
    r = check_order(order)
    A, B, C, D, delay, name = as_abcd(model)
    label = f"{name} balanced({r})"
    if _split_unstable(A):
        import control as ct

        n_unstable = int(np.count_nonzero(np.linalg.eigvals(A).real >= 0))
        if n_unstable > r:
            raise DataError(f"the model has {n_unstable} poles with Re >= 0, more than "
                            f"order={r}; ask for order >= {n_unstable}")
        red = ct.balred(ct.ss(A, B, C, [[D]]), r, method="truncate")
        return StateSpaceModel(red.A, red.B, red.C, float(red.D[0, 0]), delay, label)
    if r >= A.shape[0]:
        return StateSpaceModel(A, B, C, D, delay, label)
    Ar, Br, Cr, _ = ab09ad(A, B, C, r, "C")
    return StateSpaceModel(Ar, Br, Cr, D, delay, label)


def balanced_truncation_error_bound(model, order):
    """The a-priori bound ``2 * sum of the discarded Hankel singular values``.

    Parameters
    ----------
    model : StateSpaceModel, RationalDelayModel or control.StateSpace
    order : int
        The order r kept by :func:`balanced_truncation`.

    Returns
    -------
    float
        ``2 sum_{i > r} sigma_i`` (absolute H-infinity error bound, same units as G).
        Every HSV is counted with its multiplicity, which can only loosen the bound.
        For a model with unstable poles the count r includes them, and the sum runs over
        the discarded HSVs of the stable part.
    """
    r = check_order(order)
    A = as_abcd(model)[0]
    n_unstable = int(np.count_nonzero(np.linalg.eigvals(A).real >= 0)) if A.shape[0] else 0
    hsv = hankel_singular_values(model)
    return float(2.0 * np.sum(hsv[max(r - n_unstable, 0):]))

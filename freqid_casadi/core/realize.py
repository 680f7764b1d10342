"""A well-scaled state-space realization of a model's rational part (layer L1).

:meth:`~freqid_casadi.core.model.RationalDelayModel.to_control` realises the rational part
``K (1/s)^k P_N(s)`` here, block by block from its poles and zeros, each block on its own
frequency scale:

- a complex pole pair ``|p| = w0``: the companion form of ``H(sigma)``, ``sigma = s / w0``,
  its numerator divided by its largest coefficient, time-scaled (``A = w0 A_sigma``,
  ``B = sqrt(w0) B_sigma``, ``C = sqrt(w0) C_sigma``), so every entry is of order ``w0``;
- real poles: first-order blocks ``(s - z) / (s - p)`` (a real zero each, paired by size)
  on the scale ``|p|``; two real poles carrying a complex zero pair: the companion form on
  the scale ``sqrt(|p1 p2|)``;
- a pole at the origin: ``1 / s``.

A section's polynomial coefficients can span twenty decades (a real pole far above the
band: ``b`` tiny against ``omega_d^2``; a tiny gain against a far zero pair): expanded
into one transfer function and converted, such a section gave a realization whose
frequency response was off by 790 % and whose DC gain had the wrong sign (a Siglent Bode
export fitted at 2 sections: a pole at -3.7e15 rad/s). The blocks carry no gain of
their own; the model's gain is measured against its own evaluation
(:meth:`~freqid_casadi.core.model.RationalDelayModel.rational_response`) and spread over
the blocks.
"""

import math

import numpy as np

from ..errors import StructureError

__all__ = ["realize_blocks", "state_space", "export_error", "quad_roots", "section_roots",
           "balanced_ss", "EXPORT_TOLERANCE", "check_pade", "PADE_TOLERANCE",
           "RESPONSE_FLOOR"]

#: Largest relative difference between an exported system's response and the model's
#: before :meth:`~freqid_casadi.core.model.RationalDelayModel.to_control` warns.
EXPORT_TOLERANCE = 1e-6


def quad_roots(c2, c1, c0):
    """Roots of c2 s^2 + c1 s + c0 (c2 may be 0); returns a list of complex.

    For the coefficients of a model (all >= 0) the closed form keeps the sign of every real
    part exact: 0 for c1 = 0 (an undamped pair on the imaginary axis), else < 0.

    Parameters
    ----------
    c2, c1, c0 : float
        The coefficients, highest first.
    """
    if c2 == 0:
        return [complex(-c0 / c1)] if c1 != 0 else []
    if min(c2, c1, c0) >= 0:
        with np.errstate(all="ignore"):
            p, q = c1 / (2.0 * c2), c0 / c2            # s^2 + 2 p s + q
        if not (np.isfinite(p) and np.isfinite(q)):     # c2 negligible: one finite root
            return [complex(-c0 / c1)] if c1 != 0 else []
        if p < 1e150:
            disc = p * p - q
            if disc < 0:
                im = float(np.sqrt(-disc))
                return [complex(-p, im), complex(-p, -im)]
            sd = float(np.sqrt(disc))
        else:
            r = q / p / p                               # disc = p^2 (1 - r), no overflow
            if r > 1:
                im = p * float(np.sqrt(r - 1.0))
                return [complex(-p, im), complex(-p, -im)]
            sd = p * float(np.sqrt(1.0 - r))
        big = -(p + sd)                                 # no cancellation
        return [complex(big), complex(q / big if big != 0 else 0.0)]
    return list(np.roots([c2, c1, c0]).astype(complex))


def balanced_ss(sys):
    """``sys`` (python-control StateSpace) after a diagonal similarity by powers of two
    that balances the row and column norms of A (LAPACK's gebal, no permutation).

    Series connections of sections whose coefficients span many decades (a zero far
    above the band) give A, B, C entries 1e7 apart; evaluating or synthesising with that
    realization loses digits (python-control's frequency response of such a model was
    off by 4e-4, and slycot's H-infinity synthesis refused it). The transform is exact in
    floating point (powers of two), so poles, zeros and the response are unchanged.

    Parameters
    ----------
    sys : control.StateSpace

    Returns
    -------
    control.StateSpace
        The same system; its attribute ``delay`` is kept.
    """
    import control as ct
    from scipy.linalg import matrix_balance

    a = np.asarray(sys.A, float)
    if a.size == 0:
        return sys
    _, (scale, _) = matrix_balance(a, permute=False, separate=True)
    out = ct.ss(a * scale[None, :] / scale[:, None], np.asarray(sys.B) / scale[:, None],
                np.asarray(sys.C) * scale[None, :], sys.D)
    if hasattr(sys, "delay"):
        out.delay = sys.delay
    return out


def section_roots(basis, theta):
    """``(zeros, poles)`` of one section, lists of complex (:func:`quad_roots`; a first-order
    section's numerator and denominator as ``0 s^2 + c1 s + c0``).

    Parameters
    ----------
    basis : {"second-order", "first-order"}
    theta : sequence of float
        The section's parameters, in :attr:`Structure.param_names` order.

    Returns
    -------
    (list of complex, list of complex)
    """
    if basis == "second-order":
        a, zn, wn, b, zd, wd = theta
        return quad_roots(a, 2 * zn * wn, wn * wn), quad_roots(b, 2 * zd * wd, wd * wd)
    a1, a0, b1, b0 = theta
    return quad_roots(0.0, a1, a0), quad_roots(0.0, b1, b0)


def _poly(roots):
    """Real coefficients (highest first) of the monic polynomial with ``roots``."""
    return np.real(np.poly(np.asarray(roots, complex))) if len(roots) else np.array([1.0])


def _companion(zeros, poles):
    """A second-order block for a pole pair (and up to two zeros) on the scale
    ``sqrt(|p1 p2|)``: the modulus of a complex pair."""
    w0 = math.sqrt(abs(poles[0] * poles[1]))
    scale = w0 if w0 > 0 else 1.0
    den = _poly(np.asarray(poles) / scale)                  # sigma^2 + 2 zeta sigma + 1
    num = _poly(np.asarray(zeros) / scale)
    num = np.concatenate([np.zeros(3 - num.size), num])
    num = num / np.max(np.abs(num))
    d = num[0]
    a = np.array([[0.0, 1.0], [-den[2], -den[1]]])
    b = np.array([[0.0], [1.0]])
    c = np.array([[num[2] - d * den[2], num[1] - d * den[1]]])
    return scale * a, math.sqrt(scale) * b, math.sqrt(scale) * c, np.array([[d]])


def _first_order(zero, pole):
    """``(s - zero) / (s - pole)`` (``zero`` None: ``1 / (s - pole)``), up to a gain."""
    scale = abs(pole) if pole != 0 else 1.0
    p = pole / scale
    if zero is None:
        n1, n0 = 0.0, 1.0
    else:
        n1, n0 = 1.0, -zero / scale
        m = max(abs(n1), abs(n0))
        n1, n0 = n1 / m, n0 / m
    # H(sigma) = n1 + (n0 + n1 p) / (sigma - p)
    r = n0 + n1 * p
    return (np.array([[scale * p]]), np.array([[math.sqrt(scale)]]),
            np.array([[math.sqrt(scale) * r]]), np.array([[n1]]))


def _section_blocks(zeros, poles):
    """The blocks of one section's roots (conjugate-closed lists of complex)."""
    if len(zeros) > len(poles):
        raise StructureError("section is improper (numerator degree > denominator's); "
                             "cannot export to a state-space model")
    poles = [complex(p) for p in poles]
    zeros = [complex(z) for z in zeros]
    if len(poles) == 2 and poles[0].imag != 0:
        return [_companion(zeros, poles)]
    poles = sorted((p.real for p in poles), key=abs)
    if len(zeros) == 2 and zeros[0].imag != 0:
        return [_companion(zeros, poles)]        # on the scale sqrt(|p1 p2|)
    zeros = sorted((z.real for z in zeros), key=abs)
    zeros = zeros + [None] * (len(poles) - len(zeros))
    return [_first_order(z, p) for z, p in zip(zeros, poles)]


def _response(blocks, omega):
    """The product of the blocks' frequency responses at ``omega`` (1-D)."""
    out = np.ones(omega.size, complex)
    for a, b, c, d in blocks:
        n = a.shape[0]
        for i, w in enumerate(omega):
            x = np.linalg.solve(1j * w * np.eye(n) - a, b) if n else np.zeros((0, 1))
            out[i] *= (c @ x + d)[0, 0]
    return out


def realize_blocks(model):
    """The blocks ``[(A, B, C, D), ...]`` (in series, input first) of ``model``'s rational
    part ``K (1/s)^k P_N(s)``, the gain spread over them (module docstring).

    Parameters
    ----------
    model : RationalDelayModel

    Returns
    -------
    list of tuple of ndarray
        Each ``(A (n, n), B (n, 1), C (1, n), D (1, 1))``, real.

    Raises
    ------
    StructureError
        An improper section, or more zeros at the origin than the sections have poles to
        spare.
    """
    k = model.origin_order
    spare = max(-k, 0)                       # -k zeros at the origin: into the sections
    blocks = [(np.zeros((1, 1)), np.ones((1, 1)), np.ones((1, 1)), np.zeros((1, 1)))
              for _ in range(max(k, 0))]
    for theta in model.sections():
        zeros, poles = section_roots(model.structure.basis, theta)
        while spare and len(zeros) < len(poles):
            zeros, spare = zeros + [0j], spare - 1
        blocks += _section_blocks(zeros, poles)
    if spare:
        raise StructureError(
            f"{-k} zeros at the origin need as many poles in the sections (the model is "
            f"improper: it grows as s^{spare} above its roots, as an accelerance fitted with "
            "integrator=-2 does); cannot export to a state-space model. Export the same "
            "sections without the zeros at the origin, RationalDelayModel(dataclasses."
            f"replace(model.structure, integrator=False), model.beta) (G / s^{-k}, e.g. the "
            f"displacement of an accelerance), and put the s^{-k} back in the design")
    gain = _gain(model, blocks)
    share = abs(gain) ** (1.0 / len(blocks)) if blocks and gain != 0 else 1.0
    if not blocks:
        return [(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.array([[gain]]))]
    out = []
    for j, (a, b, c, d) in enumerate(blocks):
        f = share * (math.copysign(1.0, gain) if j == 0 else 1.0)
        out.append((a, b, f * c, f * d))
    return out


def _gain(model, blocks):
    """The real factor by which the model's response exceeds the blocks' product: the
    median over frequencies across its roots' range (a frequency near a root or where
    either evaluation loses digits is outvoted)."""
    omega = _check_omega(model)
    with np.errstate(all="ignore"):
        ratio = _reference(model, omega) / _response(blocks, omega)
    ratio = ratio[np.isfinite(ratio)]
    if ratio.size == 0:
        return float(model.gain)
    return float(np.median(ratio.real))


def state_space(model):
    """The rational part of ``model`` as a python-control ``StateSpace`` (no delay), and
    whether to balance it again once the delay's Pade states are attached.

    The blocks of :func:`realize_blocks` in series; the series order and a balancing
    (:func:`balanced_ss`) change how well python-control evaluates the system when its
    roots span many decades (a Siglent export's fit, roots from 2e4 to 3.7e15 rad/s:
    6e-5 as built, 26 balanced, 1e-8 with the fast block at the input, balanced): the best
    of three orders (as built, fast first, slow first), balanced or not, as measured by
    :func:`export_error`, is kept. Where even that misses :data:`EXPORT_TOLERANCE`, an
    :class:`~freqid_casadi.errors.ExportWarning` gives the error and the roots' span.

    Parameters
    ----------
    model : RationalDelayModel

    Returns
    -------
    (control.StateSpace, bool)
        The system in series, and whether it is kept balanced (the caller balances it
        once the delay is attached).

    Raises
    ------
    StructureError
        As :func:`realize_blocks`.
    """
    import control as ct

    blocks = [ct.ss(*b) for b in realize_blocks(model)]
    scale = [float(np.max(np.abs(b.A))) if b.nstates else 0.0 for b in blocks]
    omega = _check_omega(model)
    want = _reference(model, omega)
    best = None
    for order in (range(len(blocks)), np.argsort(scale)[::-1], np.argsort(scale)):
        sys = blocks[order[0]]
        for j in order[1:]:
            sys = ct.series(sys, blocks[j])
        for balance in (True, False):
            error = _error(balanced_ss(sys) if balance else sys, omega, want,
                           model.origin_order)
            if best is None or error < best[0]:
                best = (error, sys, balance)
    error, sys, balance = best
    if error > EXPORT_TOLERANCE:
        import warnings

        from ..errors import ExportWarning

        lo, hi = _root_range(model)
        warnings.warn(
            f"the exported system's frequency response differs from the model's by up "
            f"to {error:.2g} (relative, within 120 dB of its peak): its poles and zeros span {np.log10(hi / lo):.0f} "
            f"decades ({lo:.3g} to {hi:.3g} rad/s), beyond what a state-space evaluation "
            "resolves: the roots far from the band are not set by the data (zeros running "
            "off towards infinity stand for the relative degree the data show); fit fewer "
            "sections before designing with it, or evaluate the model itself "
            "(model.frequency_response) where the accuracy matters",
            ExportWarning, stacklevel=3)
    return sys, balance


def export_error(sys, model):
    """Largest relative difference between ``sys``'s frequency response (python-control's
    own evaluation, as a design tool sees it) and ``model``'s rational part, over the
    frequencies of :func:`_check_omega` (where the response is more than 120 dB below its
    largest there, :data:`RESPONSE_FLOOR`, the difference counts against that level).

    Parameters
    ----------
    sys : control.StateSpace
        A realization of ``model``'s rational part (no delay).
    model : RationalDelayModel

    Returns
    -------
    float
        inf where either response is not finite.
    """
    omega = _check_omega(model)
    return _error(sys, omega, _reference(model, omega), model.origin_order)


def _reference(model, omega):
    """The model's own rational response at ``omega`` (what a realization must match)."""
    with np.errstate(all="ignore"):
        return model.rational_response(omega)


#: Level below the largest response over the check's frequencies (-120 dB) where an
#: export's error counts against that level instead of the response itself: far above
#: the band, where a model's spare zeros sit and its response is negligible, a relative
#: error of 2e-3 at |G| = 1e-12 is no error a design sees.
RESPONSE_FLOOR = 1e-6


def _error(sys, omega, want, k=0):
    """Largest relative error of ``sys`` against ``want`` at ``omega``, against
    :data:`RESPONSE_FLOOR` times the peak where the response is lower (the peak of the
    response without its ``k`` poles at the origin, whose ``1/s^k`` would put it at the
    lowest frequency checked, outside any band)."""
    import control as ct

    with np.errstate(all="ignore"):
        got = np.squeeze(ct.frequency_response(sys, omega).complex)
        level = _without_origin(want, omega, k)
        floor = RESPONSE_FLOOR * np.max(level) / omega ** float(k)
        err = np.abs(got - want) / np.maximum(np.abs(want), floor)
    return float(np.max(err)) if np.all(np.isfinite(err)) else math.inf


def _without_origin(response, omega, k):
    """``|response| * omega^k``: the magnitude without the ``k`` poles at the origin (``k``
    < 0: zeros), whose ``1/s^k`` alone would put its peak at the lowest frequency."""
    return np.abs(response) * omega ** float(k)


#: Relative error of the delay's Pade approximation, where the model's dynamics reach,
#: above which :func:`check_pade` warns.
PADE_TOLERANCE = 0.01


def _pade_error(ct, delay, order, omega):
    """``|pade(j omega) exp(j omega h) - 1|`` of the order-``order`` Pade approximation of
    ``delay`` at ``omega`` (inf where python-control's coefficients are not finite)."""
    try:
        with np.errstate(all="raise"):
            num, den = ct.pade(delay, order)
    except (ArithmeticError, FloatingPointError, ValueError):
        return math.inf
    s = 1j * omega
    with np.errstate(all="ignore"):
        return float(abs(np.polyval(num, s) / np.polyval(den, s) * np.exp(s * delay) - 1))


#: Level below the peak of the response (-60 dB) up to which :func:`check_pade` looks.
PADE_LEVEL = 1e-3


def _dynamics_top(model, poles):
    """Twice the fastest pole, or the highest frequency where the response (without its
    poles at the origin) is within :data:`PADE_LEVEL` of its peak, if lower: a spare pole
    far above the band, where the response has long fallen away, sets nothing."""
    lo, _ = _root_range(model)
    top = 2.0 * float(np.max(poles))
    grid = np.geomspace(min(lo, top) / 10, top, 400)
    with np.errstate(all="ignore"):
        size = _without_origin(model.rational_response(grid), grid, model.origin_order)
    ok = np.isfinite(size)
    if not ok.any():
        return top
    within = grid[ok][size[ok] >= PADE_LEVEL * np.max(size[ok])]
    return float(min(top, within.max())) if within.size else top


def check_pade(model, order):
    """An :class:`~freqid_casadi.errors.ExportWarning` when the Pade approximation of
    ``model``'s delay of order ``order`` misses ``exp(-s h)`` by more than
    :data:`PADE_TOLERANCE` where the model's dynamics reach (:func:`_dynamics_top`), with
    the order that would meet it.

    Parameters
    ----------
    model : RationalDelayModel
    order : int
    """
    import control as ct

    poles = np.abs(model.poles())
    poles = poles[np.isfinite(poles) & (poles > 0)]
    if model.delay <= 0 or not poles.size:
        return
    omega = _dynamics_top(model, poles)
    err = _pade_error(ct, model.delay, order, omega)
    if not err > PADE_TOLERANCE:                 # (nan: an evaluation that overflowed)
        return
    import warnings

    from ..errors import ExportWarning

    enough = next((k for k in range(order + 1, 21)
                   if _pade_error(ct, model.delay, k, omega) <= PADE_TOLERANCE), None)
    fix = (f"pass pade_order={enough}" if enough is not None else
           "no Pade order up to 20 is accurate there")
    warnings.warn(
        f"the Pade approximation of order {order} of the delay {model.delay:.4g} s differs "
        f"from exp(-s h) by {err:.2g} (relative) at {omega:.4g} rad/s, where the model's "
        f"dynamics reach (twice its fastest pole, or where its response falls 60 dB below "
        f"its peak; a phase lag of {omega * model.delay:.3g} rad there): the exported "
        f"system misses the delay's phase within the model's dynamics; {fix}, or export "
        "the delay exactly (delay='attribute') and check margins on the model's frequency "
        "response", ExportWarning, stacklevel=3)


def _root_range(model):
    """Smallest and largest modulus of the model's nonzero finite poles and zeros (1, 1
    without any)."""
    roots = np.abs(np.concatenate([model.poles(), model.zeros()]))
    roots = roots[(roots > 0) & np.isfinite(roots)]
    return (float(roots.min()), float(roots.max())) if roots.size else (1.0, 1.0)


def _check_omega(model):
    """15 frequencies from a decade below the model's smallest nonzero root to a decade
    above its largest (1 rad/s without roots)."""
    lo, hi = _root_range(model)
    return np.geomspace(lo / 10, hi * 10, 15)

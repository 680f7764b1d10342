"""Tests of freqid_casadi.fitting.validation: the resolution check and the pruning safeguard."""

import numpy as np
import pytest

from freqid_casadi.core.data import FrequencyData
from freqid_casadi.errors import DataError, OptionError
from freqid_casadi.core.model import RationalDelayModel, Structure
from freqid_casadi.fitting.validation import (PairFlag, check_resolution, dense_grid,
                                      prune_sections)

OMEGA = np.logspace(-1, 2, 120)          # spacing 0.059 * omega
# a well-resolved two-mode model: zeta 0.05 / 0.1 (bandwidth 0.1-0.2 omega), no delay
TRUE = [0.0, 2.0, 1, 0.1, 2.0, 1, 0.05, 3.0, 1, 0.1, 20.0, 1, 0.05, 30.0]


def _true_model():
    return RationalDelayModel(Structure(2, integrator=False, delay=False), np.array(TRUE))


def _with_narrow_pair(omega_c, zeta_zero=1e-3, zeta_pole=1e-7):
    """The true model times a near-cancelling section at omega_c, far narrower than the
    grid spacing there."""
    beta = np.concatenate([TRUE, [1, zeta_zero, omega_c, 1, zeta_pole, omega_c]])
    return RationalDelayModel(Structure(3, integrator=False, delay=False), beta)


def _between_samples():
    i = 60
    return float(np.sqrt(OMEGA[i] * OMEGA[i + 1]))     # geometric midpoint: no sample there


def test_well_resolved_model_passes():
    check = check_resolution(_true_model(), OMEGA)
    assert check.ok
    assert check.flags == () and check.narrow == ()


def test_narrow_near_cancelling_pair_is_flagged():
    w = _between_samples()
    check = check_resolution(_with_narrow_pair(w), OMEGA)
    assert not check.ok
    assert len(check.flags) == 1
    flag = check.flags[0]
    assert isinstance(flag, PairFlag)
    assert flag.sections == (2,)
    assert flag.pole.zeta == pytest.approx(1e-7)
    assert flag.pole.bandwidth < flag.pole.spacing
    assert "near-cancelling" in check.message()


def test_narrow_resonance_that_does_not_cancel_is_only_reported():
    # zero at 2, pole at 5 rad/s, pole narrower than the spacing: a true sharp mode
    beta = np.concatenate([TRUE, [1, 0.3, 2.0, 1, 0.01, 5.0]])
    model = RationalDelayModel(Structure(3, integrator=False, delay=False), beta)
    check = check_resolution(model, OMEGA)
    assert check.ok
    assert [(q.kind, q.section) for q in check.narrow] == [("pole", 2)]
    assert check.unresolved == ()


def test_undamped_pole_between_samples_fails_the_check():
    beta = np.concatenate([TRUE, [1, 0.3, 2.0, 1, 1e-11, 5.0]])
    model = RationalDelayModel(Structure(3, integrator=False, delay=False), beta)
    check = check_resolution(model, OMEGA)
    assert not check.ok and check.flags == ()
    assert [(q.kind, q.section) for q in check.unresolved] == [("pole", 2)]
    assert "100x narrower" in check.message()


def test_out_of_band_pair_is_not_flagged():
    assert check_resolution(_with_narrow_pair(1e4), OMEGA).ok


def test_prune_removes_the_pair_and_lowers_the_dense_error():
    true = _true_model()
    w = _between_samples()
    bad = _with_narrow_pair(w)
    data = FrequencyData(OMEGA, true.frequency_response(OMEGA), "two modes")

    def reference(omega):
        return true.frequency_response(omega)

    pr = prune_sections(bad, data, reference=reference)
    assert len(pr.removed) == 1 and pr.check.ok
    assert pr.model.n_sections == 2
    # the pair is invisible at the samples but huge between them
    assert pr.max_rel_error_before < 0.05
    assert pr.max_dense_error_before > max(0.1, 5 * pr.max_rel_error_before)
    assert pr.max_dense_error_after < 1e-6
    assert pr.max_rel_error_after < 1e-6
    d = pr.as_dict()
    assert d["n_sections_before"] == 3 and d["n_sections_after"] == 2


def test_prune_regroups_a_pair_from_different_sections():
    # zero of section 0 and pole of section 1 cancel near 7 rad/s
    w = _between_samples()
    beta = [0.0, 1.0, 1, 1e-6, w, 1, 0.2, 3.0, 1, 0.2, 40.0, 1, 1e-8, w * (1 + 1e-5)]
    model = RationalDelayModel(Structure(2, integrator=False, delay=False), np.array(beta))
    check = check_resolution(model, OMEGA)
    assert len(check.flags) == 1 and check.flags[0].sections == (0, 1)
    data = FrequencyData(OMEGA, model.frequency_response(OMEGA))
    pr = prune_sections(model, data, refit=False)
    assert pr.model.n_sections == 1
    # the remaining zero (40) and pole (3) form one section with the same static gain
    np.testing.assert_allclose(pr.model.frequency_response([1e-4]),
                               model.frequency_response([1e-4]), rtol=1e-6)


def test_nothing_to_prune_returns_the_model():
    true = _true_model()
    data = FrequencyData(OMEGA, true.frequency_response(OMEGA))
    pr = prune_sections(true, data)
    assert pr.removed == () and pr.model == true and pr.n_rounds == 0
    assert pr.max_dense_change < 1e-14


def test_bad_input():
    with pytest.raises(DataError, match="strictly"):
        check_resolution(_true_model(), OMEGA[::-1])
    with pytest.raises(OptionError, match="factor"):
        check_resolution(_true_model(), OMEGA, factor=-1)
    with pytest.raises(OptionError, match="RationalDelayModel"):
        check_resolution("model", OMEGA)
    with pytest.raises(OptionError, match="factor"):
        dense_grid(OMEGA, 0)
    assert dense_grid(OMEGA, 10).size == 10 * OMEGA.size

"""A shared fit with minimum-phase channels that a modal test's non-collocated sensors do
not allow: the fit with free zeros offered in its message; which channels' zeros turn the
phase in the band; the random modal tests of :mod:`freqid_casadi.studies.modal_zeros`."""

import numpy as np
import pytest

import freqid_casadi as fc
from freqid_casadi.core.model import RationalDelayModel, Structure
from freqid_casadi.modal.shared import turns_phase
from freqid_casadi.studies.modal_zeros import modal_case


def test_turns_phase_counts_right_half_plane_zeros_by_their_phase_in_the_band():
    omega = np.geomspace(1.0, 100.0, 50)
    s = Structure(1, delay=False, zeros="free")

    def model(zeros):
        # a section with the given numerator roots (a real pair), denominator 1 + s/10
        # squared: rebuild it from the free parametrisation's coefficients
        z1, z2 = zeros
        coeffs = np.poly([z1, z2]).real           # s^2 - (z1 + z2) s + z1 z2
        coeffs = coeffs / coeffs[-1]
        from freqid_casadi.core.gauges import dc_to_thesis
        a, zn, wn, _ = dc_to_thesis(coeffs[0], coeffs[1], 1.0)
        return RationalDelayModel(s, [0.0, 1.0, a, zn, wn, 1e-2, 1.0, 10.0])

    assert not turns_phase(model((-30.0, -2000.0)), omega)       # left half plane only
    assert turns_phase(model((30.0, -2000.0)), omega)            # in the band: 147 deg
    assert turns_phase(model((150.0, -2000.0)), omega)           # 1.5 x the top: 67 deg
    assert not turns_phase(model((5000.0, -5000.0)), omega)      # far beyond: 2.3 deg


def test_a_poor_minimum_phase_shared_fit_offers_free_zeros():
    # case 19 of the study: 3 modes, 3 sensors (the first at the drive), 1.2 % noise
    case = modal_case(19)
    res = fc.fit_shared(case["datas"], 3, delay=False)
    assert res.status != "ok"
    offer = res.details["free_zeros"]
    assert offer["status"] == "ok"
    assert max(offer["rms_rel_errors"]) < 0.02 < 0.5 * np.max(res.rms_rel_errors)
    # the driving point is minimum phase: never named
    assert 0 not in offer["non_minimum_phase"] and offer["non_minimum_phase"]
    assert "with free zeros the same fit reaches worst-channel RMS" in res.message
    assert "pass zeros='free' (freqid modal --zeros free)" in res.message
    assert "pass n_sections" not in res.message        # the zeros, not the order
    free = fc.fit_shared(case["datas"], 3, delay=False, zeros="free")
    assert free.status == "ok" and "free_zeros" not in free.details
    np.testing.assert_allclose(sorted(m.omega_n for m in free.modes), case["omega_n"],
                               rtol=1e-3)
    np.testing.assert_allclose(free.rms_rel_errors, offer["rms_rel_errors"], rtol=1e-9)


def test_an_ok_minimum_phase_fit_offers_nothing():
    # the driving point alone is minimum phase
    case = modal_case(19)
    res = fc.fit_shared(case["datas"][:1], 3, delay=False)
    assert res.status == "ok" and "free_zeros" not in res.details


@pytest.mark.parametrize("index", [0, 7])
def test_modal_cases_are_seeded_and_collocated_first(index):
    a, b = modal_case(index), modal_case(index)
    np.testing.assert_array_equal(a["datas"][1].response, b["datas"][1].response)
    assert np.all(a["shapes"][0] > 0)                  # phi_0k^2: the driving point
    assert 2 <= len(a["omega_n"]) <= 5 and 3 <= len(a["datas"]) <= 6

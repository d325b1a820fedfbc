"""Ideal couplers: unitarity, orthonormal maps and the paper's Eq. 28 and Eq. 29."""

from __future__ import annotations

import numpy as np
import pytest

from wavemeter.exceptions import InputError
from wavemeter.model.couplers import (
    equally_spaced_phases_rad,
    fourier_matrix,
    mmi_2x2,
    mmi_matrix,
    orthonormal_map,
    port_phases_rad,
    y_junction,
)

EQ28 = np.array(
    [
        [-np.sqrt(3) / np.sqrt(2), -1 / np.sqrt(2), 1],
        [0, np.sqrt(2), 1],
        [np.sqrt(3) / np.sqrt(2), -1 / np.sqrt(2), 1],
    ]
) / np.sqrt(3)
EQ29 = np.array([[-1, 1, 1], [-1, -1, 1], [1, 1, 1], [1, -1, 1]]) / 2.0


@pytest.mark.parametrize("n", [2, 3, 4, 5, 8, 16])
@pytest.mark.parametrize("build", [fourier_matrix, mmi_matrix])
def test_unitary(build, n):
    matrix = build(n)
    assert np.abs(matrix.conj().T @ matrix - np.eye(n)).max() < 1e-12


def test_fourier_matrix_entries():
    w = np.exp(-2j * np.pi / 3)
    expected = np.array([[1, 1, 1], [1, w, w**2], [1, w**2, w**4]]) / np.sqrt(3)
    np.testing.assert_allclose(fourier_matrix(3), expected, atol=1e-15)


def test_splitters_send_half_the_power_to_each_arm():
    np.testing.assert_allclose(np.abs(mmi_2x2()) ** 2, 0.5, atol=1e-15)
    np.testing.assert_allclose(np.abs(y_junction()) ** 2, 0.5, atol=1e-15)
    # the 2x2 MMI's cross port is in quadrature with its bar port
    assert abs(np.angle(mmi_2x2()[1, 0] / mmi_2x2()[0, 0])) == pytest.approx(np.pi / 2)


@pytest.mark.parametrize("n", [3, 4, 5, 8])
def test_mmi_is_phase_permutation_equivalent_to_fourier(n):
    """|M| is flat like F, and each pair of ports fed from the MMI sees a DFT phase step."""
    np.testing.assert_allclose(np.abs(mmi_matrix(n)), 1 / np.sqrt(n), atol=1e-15)
    phases = np.sort(port_phases_rad(mmi_matrix(n), (0, 1)) % (2 * np.pi))
    steps = np.diff(np.concatenate([phases, [phases[0] + 2 * np.pi]]))
    np.testing.assert_allclose(steps, 2 * np.pi / n, atol=1e-12)


@pytest.mark.parametrize("n", [3, 4, 5, 8])
def test_orthonormal_map(n):
    o = orthonormal_map(equally_spaced_phases_rad(n))
    np.testing.assert_allclose(o.T @ o, np.eye(3), atol=1e-12)
    # shuffled port order is still orthonormal
    o = orthonormal_map(np.random.default_rng(n).permutation(equally_spaced_phases_rad(n)))
    np.testing.assert_allclose(o.T @ o, np.eye(3), atol=1e-12)


def _match_up_to_rotation(o: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """The 2x2 matrix Q with o[:, :2] @ Q closest to reference[:, :2]."""
    q, *_ = np.linalg.lstsq(o[:, :2], reference[:, :2], rcond=None)
    return q


@pytest.mark.parametrize(("n", "reference"), [(3, EQ28), (4, EQ29)])
def test_mmi_fed_at_inputs_1_and_3_gives_paper_map(n, reference):
    o = orthonormal_map(port_phases_rad(mmi_matrix(n), (0, 2)))
    np.testing.assert_allclose(o.T @ o, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(reference.T @ reference, np.eye(3), atol=1e-12)
    q = _match_up_to_rotation(o, reference)
    # Q is a rotation or a reflection (phase origin and direction), and matches exactly
    np.testing.assert_allclose(q.T @ q, np.eye(2), atol=1e-12)
    np.testing.assert_allclose(o[:, :2] @ q, reference[:, :2], atol=1e-12)
    np.testing.assert_allclose(o[:, 2], reference[:, 2], atol=1e-12)


@pytest.mark.parametrize(("n", "spacing_deg"), [(3, 120.0), (4, 90.0)])
def test_port_fringes_are_equally_spaced(n, spacing_deg):
    phases = np.sort(np.degrees(port_phases_rad(mmi_matrix(n), (0, 2))) % 360)
    gaps = np.diff(np.concatenate([phases, [phases[0] + 360]]))
    np.testing.assert_allclose(gaps, spacing_deg, atol=1e-9)


def test_4x4_inputs_1_and_4_are_degenerate():
    phases = np.degrees(port_phases_rad(mmi_matrix(4), (0, 3))) % 360
    assert len(np.unique(np.round(phases, 6))) == 2


def test_orthonormal_map_rejects_bad_phases():
    with pytest.raises(ValueError, match="ports must be >= 3"):
        orthonormal_map([0.0, 1.0])
    with pytest.raises(ValueError, match="finite"):
        orthonormal_map([0.0, np.nan, 1.0])
    with pytest.raises(InputError, match="ports must be an integer"):
        fourier_matrix(3.5)

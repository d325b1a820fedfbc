"""Identification of found lines with table lines: unique, or refused with the reason."""

from __future__ import annotations

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.reference import identify_lines
from wavemeter.simulation import simulated_band_lines

LINES, _ = simulated_band_lines()
FSR_HZ = 49.6e9
ORIGIN_HZ = 193.4e12


def phase_of(frequency_hz, dispersion=0.0):
    """The meter's phase at frequencies: linear, with a little dispersion."""
    offset = np.asarray(frequency_hz) - ORIGIN_HZ
    return 2 * np.pi * offset / FSR_HZ + dispersion * (offset / 1e12) ** 2


def labels_of(identification):
    return [LINES.labels[k] for k in identification.table_index]


@pytest.mark.parametrize("sign", [1, -1])
def test_whole_band_identified_by_its_pattern_in_either_direction(sign):
    rng = np.random.default_rng(1)
    positions = sign * phase_of(LINES.center_hz, dispersion=0.05) + rng.normal(0, 1e-4, 54)
    found = identify_lines(positions[::-1], LINES)  # record order is irrelevant
    assert found.method == "pattern"
    assert labels_of(found) == list(LINES.labels[::-1])
    assert f"direction {sign:+d}" in found.detail


def test_part_of_the_band_with_the_origin_gap_is_unique_in_a_known_direction():
    chosen = np.arange(23, 30)  # P(4) .. R(2)
    assert LINES.labels[chosen[0]] == "sim P(4)" and LINES.labels[chosen[-1]] == "sim R(2)"
    positions = phase_of(LINES.center_hz[chosen])
    found = identify_lines(positions, LINES, direction=1)
    np.testing.assert_array_equal(found.table_index, chosen)
    # in an unknown direction the few lines about the gap mirror onto R(3) .. P(3)
    with pytest.raises(wm.InputError, match=r"sim R\(3\) .. sim P\(3\), direction -1"):
        identify_lines(positions, LINES)


def test_a_missed_line_is_refused_unless_allowed():
    chosen = np.r_[10:20, 21:40]  # P(16) not detected; the band origin inside
    positions = phase_of(LINES.center_hz[chosen])
    with pytest.raises(wm.InputError, match="no assignment|a line missed between others"):
        identify_lines(positions, LINES, frequency_std_hz=5e6)
    found = identify_lines(positions, LINES, allow_missing=True, frequency_std_hz=5e6)
    np.testing.assert_array_equal(found.table_index, chosen)


def test_one_branch_without_a_feature_is_refused_as_ambiguous():
    chosen = np.arange(10, 20)  # P(17)..P(8): no band gap, no band end
    with pytest.raises(wm.InputError, match="cannot be identified uniquely") as caught:
        identify_lines(phase_of(LINES.center_hz[chosen]), LINES)
    message = str(caught.value)
    assert "assignments fit their spacings" in message and "sweep across one" in message
    assert caught.value.parameter == "reference_lines"


def test_the_band_fixes_a_branch_when_all_its_lines_are_found():
    chosen = np.arange(10, 20)
    band = (LINES.center_hz[10] - 20e9, LINES.center_hz[19] + 20e9)
    positions = phase_of(LINES.center_hz[chosen])
    found = identify_lines(positions, LINES, band_hz=band, direction=1)
    np.testing.assert_array_equal(found.table_index, chosen)
    with pytest.raises(wm.InputError, match="direction -1"):  # the branch reversed fits too
        identify_lines(positions, LINES, band_hz=band)


def test_a_known_scale_fixes_a_branch():
    chosen = np.arange(10, 20)
    scale = FSR_HZ / (2 * np.pi)
    found = identify_lines(
        phase_of(LINES.center_hz[chosen]),
        LINES,
        direction=1,
        scale_range=(0.995 * scale, 1.005 * scale),
    )
    np.testing.assert_array_equal(found.table_index, chosen)


def test_nearest_line_where_the_axis_is_good_to_a_quarter_spacing():
    rng = np.random.default_rng(2)
    chosen = np.arange(12, 16)  # a few lines of one branch: the pattern alone is ambiguous
    approx = LINES.center_hz[chosen] + rng.uniform(-1.2e9, 1.2e9, chosen.size)
    found = identify_lines(
        phase_of(LINES.center_hz[chosen]), LINES, approx_hz=approx, axis_error_hz=1.3e9
    )
    assert found.method == "nearest"
    np.testing.assert_array_equal(found.table_index, chosen)


def test_an_axis_worse_than_stated_falls_back_to_the_pattern_and_says_so():
    chosen = np.arange(20, 40)  # across the band origin
    approx = LINES.center_hz[chosen] + 3e9
    found = identify_lines(
        phase_of(LINES.center_hz[chosen]), LINES, approx_hz=approx, axis_error_hz=1.3e9
    )
    assert found.method == "pattern" and "beyond the stated axis error" in found.detail
    np.testing.assert_array_equal(found.table_index, chosen)
    with pytest.raises(wm.InputError, match="beyond the stated axis error"):
        identify_lines(  # a part of one branch: neither way works, and the reason says why
            phase_of(LINES.center_hz[12:16]),
            LINES,
            approx_hz=LINES.center_hz[12:16] + 3e9,
            axis_error_hz=1.3e9,
        )


def test_an_axis_error_of_a_quarter_spacing_is_not_trusted():
    chosen = np.arange(20, 40)
    found = identify_lines(
        phase_of(LINES.center_hz[chosen]),
        LINES,
        approx_hz=LINES.center_hz[chosen],
        axis_error_hz=30e9,
    )
    assert found.method == "pattern" and "not below a quarter" in found.detail


def test_a_dip_that_is_no_table_line_is_refused():
    frequency = np.sort(np.r_[LINES.center_hz[20:40], LINES.center_hz[30] + 37e9])
    with pytest.raises(wm.InputError, match="no assignment of the 21 lines found"):
        identify_lines(phase_of(frequency), LINES)


def test_more_dips_than_lines_in_the_band_is_refused():
    with pytest.raises(wm.InputError, match="5 lines were found but the table has 3"):
        identify_lines(
            phase_of(LINES.center_hz[20:25]),
            LINES,
            band_hz=(LINES.center_hz[20] - 1e9, LINES.center_hz[22] + 1e9),
        )

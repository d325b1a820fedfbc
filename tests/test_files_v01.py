"""Calibration files written by wavemeter 0.1 still load and predict what 0.1 predicted.

The files in ``tests/data/v0.1`` were written by wavemeter 0.1.0 (commit de7374c) together
with its predictions on 20 readings (``expected.json``); loading them with this version
must give the same numbers to the last few bits, since the learned state is stored exactly
(the last bits follow how the installed numpy, scipy and BLAS round a product, which
changes between their builds: ``ROUNDING_RAD`` of phase). The one exception is the ``"ml"``
retrieval: 0.3 solves the cone-constrained likelihood exactly (0.1 took Newton steps from
the pseudo-inverse phase), so those files agree to the rounding of that solve.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm

FOLDER = Path(__file__).parent / "data" / "v0.1"
EXPECTED = json.loads((FOLDER / "expected.json").read_text())
#: a few units in the last place of a phase of about pi (rad)
ROUNDING_RAD = 16 * np.finfo(float).eps
NAMES = sorted(path.name.removesuffix(".wmcal.json") for path in FOLDER.glob("*.wmcal.json"))


def test_every_file_has_expected_numbers():
    assert len(NAMES) == 8 and all(name in EXPECTED for name in NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_a_0_1_file_predicts_what_0_1_predicted(name):
    calibration = wm.load_calibration(FOLDER / f"{name}.wmcal.json")
    readings = np.array(EXPECTED["readings_w"])
    inputs = {"coarse_hz": np.array(EXPECTED["coarse_hz"])} if calibration.requires else {}
    expected = EXPECTED[name]
    windows = getattr(calibration, "windows_", [calibration])
    # 0.1's Newton steps for "ml" stopped within rounding of the exact optimum
    ml = getattr(windows[0], "retrieval", "pinv") == "ml"
    phase_atol = 1e-12 if ml else ROUNDING_RAD
    np.testing.assert_allclose(
        calibration.predict(readings, **inputs),
        np.array(expected["frequency_hz"]),
        rtol=4 * np.finfo(float).eps,  # the rounding of the frequency itself
        atol=phase_atol * calibration.fsr_hz_ / (2 * np.pi),
    )
    np.testing.assert_allclose(
        calibration.phase(readings, **inputs),
        np.array(expected["phase_rad"]),
        rtol=0,
        atol=phase_atol,
    )


def test_a_0_1_set_keeps_its_window_settings():
    conventional = wm.load_calibration(FOLDER / "calibration_set.wmcal.json")
    assert isinstance(conventional.window, wm.ConventionalCalibrator)
    assert conventional.window.port_phases_rad is not None
    learned = wm.load_calibration(FOLDER / "calibration_set_learned.wmcal.json")
    assert isinstance(learned.window, wm.Calibrator) and learned.window.retrieval == "ml"

"""The public namespace: every 0.1 name still resolves, and importing it stays light."""

from __future__ import annotations

import subprocess
import sys

import pytest

import wavemeter as wm

#: ``wavemeter.__all__`` of 0.1 (without ``__version__``)
NAMES_0_1 = (
    "Calibrator CalibrationSet ConventionalCalibrator EllipseCalibrator "
    "ExtendedConventionalCalibrator NonlinearFitCalibrator PlaneEllipseCalibrator "
    "EdgeMinimumError Interferometer NotFittedError cone_vectors crlb_frequency_std "
    "crlb_ideal_frequency_std error_summary_hz fourier_matrix frequency_error_hz "
    "load_calibration mmi_matrix orthonormal_map phase_to_frequency_hz predict_frequency_hz "
    "retrieve_phase_rad save_calibration write_report wrap_phase_rad"
).split()


@pytest.mark.parametrize("name", NAMES_0_1)
def test_every_0_1_name_resolves_and_is_public(name):
    assert name in wm.__all__
    assert getattr(wm, name) is not None


def test_unknown_names_raise_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'Calibrater'"):
        _ = wm.Calibrater


def test_exceptions_are_one_family():
    for error in (wm.InputError, wm.FileFormatError, wm.NotFittedError, wm.EdgeMinimumError):
        assert issubclass(error, wm.WavemeterError) and issubclass(error, ValueError)
    assert issubclass(wm.CalibrationWarning, UserWarning)


def test_import_and_help_load_no_numpy():
    code = (
        "import sys, wavemeter, wavemeter.cli; "
        "sys.exit(('numpy' in sys.modules) + 2 * ('scipy' in sys.modules))"
    )
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


def test_the_0_1_baselines_module_gives_the_public_baselines():
    from wavemeter import baselines

    classes = [name for name in baselines.__all__ if name.endswith("Calibrator")]
    assert len(classes) == 5
    for name in classes:
        assert getattr(baselines, name) is getattr(wm, name)
    for name in set(baselines.__all__) - set(classes):
        assert callable(getattr(baselines, name))


def test_dir_lists_the_public_names_and_subpackages_only():
    import wavemeter as wm

    listed = {name for name in dir(wm) if not name.startswith("__")}
    public = {name for name in wm.__all__ if not name.startswith("__")}
    subpackages = {
        "analysis",
        "calibration",
        "fleet",
        "io",
        "jobs",
        "model",
        "reference",
        "report",
        "service",
    }
    assert public | subpackages | {"simulation"} == listed

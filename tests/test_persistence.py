"""Calibration files: bit-for-bit round trips and every way a file can be wrong."""

from __future__ import annotations

import json

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.files.document import FORMAT, SCHEMA_VERSION

from .helpers import NOISE_W, POWER_W, random_test_frequencies


@pytest.fixture(scope="module")
def fitted():
    device = wm.Interferometer.table1(4, seed=21)
    rng = np.random.default_rng(21)
    f = device.sweep_hz(501)
    readings = device.powers(f, POWER_W, NOISE_W, rng)
    test = device.powers(random_test_frequencies(device, 1000, rng), POWER_W, NOISE_W, rng)
    learned = wm.Calibrator(50e9, search="brent").fit(readings, f, port_names=list("abcd"))
    conventional = wm.ConventionalCalibrator(50e9, device.design_port_phases_rad).fit(readings, f)
    return learned, conventional, test


@pytest.mark.parametrize("which", [0, 1])
def test_round_trip_predicts_bit_for_bit(fitted, tmp_path, which):
    cal, test = fitted[which], fitted[2]
    path = tmp_path / "chip.wmcal.json"
    cal.save(path)
    loaded = wm.load_calibration(path)
    assert type(loaded) is type(cal)
    assert loaded.get_params_for_file() == cal.get_params_for_file()
    np.testing.assert_array_equal(loaded.predict(test), cal.predict(test))
    np.testing.assert_array_equal(loaded.phase(test), cal.phase(test))
    for name in cal.common_attributes:
        assert getattr(loaded, name) == getattr(cal, name)


def test_file_content_names_units_and_version(fitted, tmp_path):
    path = tmp_path / "chip.wmcal.json"
    fitted[0].save(path)
    document = json.loads(path.read_text())
    assert document["format"] == FORMAT
    assert document["schema_version"] == SCHEMA_VERSION
    assert document["wavemeter_version"] == wm.__version__
    assert document["units"]["frequency"] == "Hz" and document["units"]["power"] == "W"
    assert document["port_names"] == list("abcd")
    assert document["method"] == "learned"
    assert np.array(document["state"]["map"]).shape == (4, 3)


def _write(path, document):
    path.write_text(json.dumps(document))
    return path


@pytest.mark.parametrize(
    ("mutate", "match"),
    [
        (lambda d: d.update(format="something.else"), "not a wavemeter calibration file"),
        (lambda d: d.update(schema_version=99), "schema_version 99 is not supported"),
        (lambda d: d.update(method="magic"), "unknown calibration method 'magic'"),
        (lambda d: d.update(fsr_hz="fast"), "field 'fsr_hz' must be a finite number"),
        (lambda d: d.update(n_ports=5), "port_names' must list 5 names"),
        (
            lambda d: d["state"].update(map=[[1, 2, 3]] * 3),
            r"field 'map' must be 4 x 3 finite numbers",
        ),
        (lambda d: d["state"].pop("delay_s"), "invalid 'learned' calibration state"),
        (lambda d: d["params"].update(colour="red"), "parameters do not fit method"),
    ],
)
def test_foreign_or_inconsistent_files_are_refused(fitted, tmp_path, mutate, match):
    path = tmp_path / "chip.wmcal.json"
    fitted[0].save(path)
    document = json.loads(path.read_text())
    mutate(document)
    with pytest.raises(ValueError, match=match) as info:
        wm.load_calibration(_write(path, document))
    assert str(path) in str(info.value)


def test_truncated_corrupt_and_missing_files(fitted, tmp_path):
    path = tmp_path / "chip.wmcal.json"
    fitted[0].save(path)
    text = path.read_text()
    path.write_text(text[: len(text) // 2])
    with pytest.raises(ValueError, match="corrupt or truncated"):
        wm.load_calibration(path)
    path.write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(ValueError, match="cannot read calibration file"):
        wm.load_calibration(path)
    with pytest.raises(ValueError, match="calibration file not found"):
        wm.load_calibration(tmp_path / "absent.json")


def test_save_is_atomic_and_needs_a_fit(tmp_path):
    with pytest.raises(wm.NotFittedError):
        wm.Calibrator().save(tmp_path / "x.json")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ValueError, match="does not exist"):
        wm.Calibrator().fit(
            wm.Interferometer.ideal(3).powers(np.linspace(193.38e12, 193.42e12, 9)),
            np.linspace(193.38e12, 193.42e12, 9),
        ).save(tmp_path / "missing" / "x.json")

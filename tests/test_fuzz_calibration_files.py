"""Fuzzing the calibration loader: a mutated file loads into a usable calibrator or is
refused with a WavemeterError; nothing else (no other exception, no NaN predictions).

Valid files of every calibrator are mutated as a careless editor or an attacker would:
values replaced by any JSON (wrong types, NaN, inf, huge or tiny numbers, nested
structures), keys deleted, values wrapped in lists or objects, numbers scaled. The number
of examples is ``WAVEMETER_FUZZ_EXAMPLES`` (default 200; ``make fuzz`` runs 10,000).
"""

from __future__ import annotations

import functools
import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import wavemeter as wm

from .helpers import NOISE_W, POWER_W

pytestmark = pytest.mark.slow

EXAMPLES = int(os.environ.get("WAVEMETER_FUZZ_EXAMPLES", "200"))

JSON_VALUES = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(10**20), 10**20)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.sampled_from([0.0, -0.0, 1e-320, 1e308, -1.0, 3.0, 4, 1e15, 2e14])
    | st.text(max_size=12),
    lambda children: (
        st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=6), children, max_size=4)
    ),
    max_leaves=12,
)
SCALES = st.sampled_from([0.0, -1.0, 0.5, 1.0 + 1e-6, 2.0, 1e-300, 1e300, math.nan, math.inf])
OPERATIONS = ("replace", "delete", "wrap_list", "wrap_object", "scale", "stringify")


@functools.cache
def documents() -> dict[str, dict]:
    """A saved document of every calibrator (the learned one with the ml retrieval)."""
    device = wm.Interferometer.table1(3, seed=12)
    frequency = device.sweep_hz(402, span_fsr=2.0)
    readings = device.powers(frequency, POWER_W, NOISE_W, rng=12)
    one = slice(100, 301)  # one FSR for the single-FSR calibrators
    fitted = {
        "learned": wm.Calibrator(50e9, retrieval="ml").fit(readings[one], frequency[one]),
        "set": wm.CalibrationSet(50e9).fit(readings, frequency),
        "conventional": wm.ConventionalCalibrator(50e9).fit(readings[one], frequency[one]),
        "ellipse": wm.EllipseCalibrator(50e9).fit(readings[one], frequency[one]),
        "plane": wm.PlaneEllipseCalibrator(50e9).fit(readings[one], frequency[one]),
        "extended": wm.ExtendedConventionalCalibrator(50e9).fit(readings[one], frequency[one]),
        "nonlinear": wm.NonlinearFitCalibrator(50e9).fit(readings[one], frequency[one]),
    }
    documents = {}
    with tempfile.TemporaryDirectory() as folder:
        for name, cal in fitted.items():
            path = Path(folder) / f"{name}.json"
            wm.save_calibration(cal, path, {"sweep_file": "sweep.csv", "rows": 402})
            documents[name] = json.loads(path.read_text())
    return documents


READINGS = wm.Interferometer.table1(3, seed=12).powers(
    193.4e12 + np.linspace(-20e9, 20e9, 16), POWER_W, NOISE_W, rng=13
)


def paths(node, prefix=()):
    """Every location in a JSON tree, the root included."""
    yield prefix
    if isinstance(node, dict):
        for key, child in node.items():
            yield from paths(child, (*prefix, key))
    elif isinstance(node, list):
        for index, child in enumerate(node):
            yield from paths(child, (*prefix, index))


def mutate(document, path, operation: str, value, scale: float):
    """Apply one mutation at ``path``; return the new document (the root may change)."""
    if not path:
        return value if operation == "replace" else [document]
    parent = document
    for key in path[:-1]:
        parent = parent[key]
    key = path[-1]
    current = parent[key]
    if operation == "delete":
        del parent[key]
    elif operation == "replace":
        parent[key] = value
    elif operation == "wrap_list":
        parent[key] = [current]
    elif operation == "wrap_object":
        parent[key] = {"value": current}
    elif (
        operation == "scale" and isinstance(current, (int, float)) and not isinstance(current, bool)
    ):
        parent[key] = current * scale
    elif operation == "stringify":
        parent[key] = json.dumps(current, allow_nan=True)
    return document


@st.composite
def mutated_documents(draw):
    name = draw(st.sampled_from(sorted(documents())))
    document = json.loads(json.dumps(documents()[name]))
    for _ in range(draw(st.integers(1, 3))):
        # below the root (a document that is not an object is refused at once)
        # (chosen uniformly: hypothesis would favour the first keys, the header)
        locations = list(paths(document))[1:] or [()]
        path = draw(st.randoms(use_true_random=False)).choice(locations)
        document = mutate(
            document,
            path,
            draw(st.sampled_from(OPERATIONS)),
            draw(JSON_VALUES),
            draw(SCALES),
        )
    return name, document


def usable(calibrator) -> None:
    """A loaded calibrator predicts finite numbers and reports itself."""
    inputs = {}
    if "coarse_hz" in calibrator.requires:
        low, high = calibrator.covered_hz()
        inputs["coarse_hz"] = np.full(READINGS.shape[0], 0.5 * (low + high))
    readings = READINGS if calibrator.n_ports_ == READINGS.shape[1] else None
    if readings is not None:
        assert np.all(np.isfinite(calibrator.predict(readings, **inputs)))
        assert np.all(np.isfinite(calibrator.phase(readings, **inputs)))
    assert calibrator.summary().text


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


@settings(
    max_examples=EXAMPLES,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(case=mutated_documents())
def test_a_mutated_file_loads_usable_or_is_refused(folder, case):
    name, document = case
    path = folder / f"{name}.wmcal.json"
    path.write_text(json.dumps(document, allow_nan=True))
    try:
        calibrator = wm.load_calibration(path)
    except wm.WavemeterError as exc:
        assert str(exc).startswith(str(path))
        return
    usable(calibrator)


def test_the_unmutated_files_load():
    for document in documents().values():
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "cal.json"
            path.write_text(json.dumps(document))
            usable(wm.load_calibration(path))

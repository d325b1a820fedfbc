"""Fuzzing the calibration loader: a mutated file loads into a usable calibrator or is
refused with a WavemeterError; nothing else (no other exception, no NaN predictions), and
`wavemeter info`, `measure` and `evaluate` on it exit 0 or 2 with no traceback.

Valid files of every registered calibrator are mutated as a careless editor or an attacker
would: values replaced by any JSON (wrong types, NaN, inf, huge or tiny numbers, nested
structures), keys deleted, values wrapped in lists or objects, numbers scaled. The number
of examples is ``WAVEMETER_FUZZ_EXAMPLES`` (default 200; ``make fuzz`` runs 10,000 with new
examples each run, the default run the same ones every run: the profiles in conftest).
"""

from __future__ import annotations

import json
import math
import os
import warnings

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import wavemeter as wm
from wavemeter.calibration import registered

from .saved_calibrations import INTERNALS, check_commands, documents, usable, write_test_files

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


def test_every_registered_calibrator_is_fuzzed():
    package = {tag for tag, cls in registered().items() if cls.__module__.startswith("wavemeter.")}
    assert {document["method"] for document in documents().values()} == package


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


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return write_test_files(tmp_path_factory.mktemp("fuzz"))


@pytest.mark.slow
@settings(
    max_examples=EXAMPLES,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(case=mutated_documents())
def test_a_mutated_file_loads_usable_or_is_refused(folder, case):
    name, document = case
    path = folder / f"{name}.wmcal.json"
    path.write_text(json.dumps(document, allow_nan=True))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)  # no numpy warning may leak
            calibrator = wm.load_calibration(path)
    except wm.WavemeterError as exc:
        assert str(exc).startswith(str(path))
        assert not any(internal in str(exc) for internal in INTERNALS), str(exc)
        return
    usable(calibrator, name)
    check_commands(path, calibrator, name, folder)


@pytest.mark.parametrize("name", sorted(documents()))
def test_the_unmutated_files_load_and_every_command_reads_them(folder, name):
    path = folder / f"{name}.wmcal.json"
    path.write_text(json.dumps(documents()[name]))
    calibrator = wm.load_calibration(path)
    usable(calibrator, name)
    check_commands(path, calibrator, name, folder, refusal_allowed=False)

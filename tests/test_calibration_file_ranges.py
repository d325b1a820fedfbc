"""Every number of every calibrator's file has a physical range; a file outside it is one
clean error naming the file and the field (issue 29, item 5).

Table-driven over every registered calibrator: each numeric field of its saved ``state``
and ``reading_model`` (not the windows or stages, which are calibrators of their own) is
set to 0, a negative value, 1e-307, 1e293, NaN, inf and a wrong shape. NaN, inf, 1e293 and
a wrong shape are always refused; 0, negative and 1e-307 are refused where the physics says
the quantity is positive (``POSITIVE``, ``NON_NEGATIVE``). Anything a rule lets through
must give a calibration that reads: finite frequencies and standard deviations, and
`wavemeter info`, `measure` and `evaluate` exiting 0. A refused file gives `info`,
`measure` and `evaluate` one ``error:`` line naming the calibration file and the field,
exit code 2, no output file.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration import registered
from wavemeter.calibration.files import declared_rules

from .saved_calibrations import (
    INTERNALS,
    check_commands,
    documents,
    fitted,
    run,
    usable,
    write_test_files,
)

BAD_VALUES = ("zero", "negative", "tiny", "huge", "nan", "inf", "shape")
#: bad values no number of a calibration may hold
ALWAYS_REFUSED = {"huge", "nan", "inf", "shape"}
#: fields (by their last key) of quantities that are positive and not vanishingly small:
#: noises, delays, temperatures, powers, fringe amplitudes, counts of freedom
POSITIVE = {
    "delay_s",
    "noise_std_w",
    "port_noise_std_w",
    "noise_dof",
    "reference_temperature_k",
    "temperature_range_k",
    "total_power_range_w",
    "amplitudes_w",
    "amplitude_x",
    "amplitude_y",
    "origin",
    "magnitudes",
    "phase_coefficients_rad",
    "window_edges_hz",
    "cone_distance_median",
    "ratio",
    "from_stage",
    "to_stage",
    "phase_order",
    "n_parameters",
    "phase_rad",
}
#: fields that are not zero nor vanishingly small, of either sign: the maps (a map of the
#: opposite sign is one of another device, not a number out of range)
NONZERO = {"map", "map_coefficients"}
#: fields of quantities that are never negative (but may be zero)
NON_NEGATIVE = {
    "delay_std_s",
    "cost_w2",
    "residual_rms_w",
    "model_error_hz",
    "median_std_hz",
    "largest_usable_ratio",
    "predicted_rate",
    "expected_wrong",
    "wrong_on_sweep",
    "nfev",
    "map_order",
}
#: a value so small that no physical quantity of a file holds it
TINY, HUGE = 1e-307, 1e293


def must_refuse(key: str, bad: str) -> bool:
    if bad in ALWAYS_REFUSED:
        return True
    if bad == "negative":
        return key in POSITIVE | NON_NEGATIVE
    return key in POSITIVE | NONZERO  # zero, tiny


def numeric_fields(node, path=()):
    """(path, value) of every numeric field below ``node``: a number, or lists of numbers;
    records (objects, lists of objects) are walked into."""
    if isinstance(node, dict):
        for key, child in node.items():
            if key not in ("windows", "stages"):  # calibrators of their own
                yield from numeric_fields(child, (*path, key))
    elif isinstance(node, list) and node and all(isinstance(item, dict) for item in node):
        for index, item in enumerate(node):
            yield from numeric_fields(item, (*path, index))
    elif _numbers_only(node):
        yield path, node


def _numbers_only(node) -> bool:
    if isinstance(node, bool):
        return False
    if isinstance(node, (int, float)):
        return True
    return isinstance(node, list) and bool(node) and all(map(_numbers_only, node))


def bad_value(value, bad: str):
    """``value`` (a number or nested lists of numbers) with every number made ``bad``, or
    of another shape."""
    if bad == "shape":
        return [value, value] if not isinstance(value, list) else [*value, value[0]]
    if isinstance(value, list):
        return [bad_value(item, bad) for item in value]
    return {
        "zero": 0.0,
        "negative": -abs(value) if value else -1.0,
        "tiny": TINY,
        "huge": HUGE,
        "nan": math.nan,
        "inf": math.inf,
    }[bad]


def field_name(path) -> str:
    """How the field reads in messages below its section: ``handovers[0].ratio``."""
    text = ""
    for part in path[1:]:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else part)
    return text


def cases():
    for name, document in sorted(documents().items()):
        for section in ("state", "reading_model"):
            for path, _ in numeric_fields(document[section], (section,)):
                yield name, path


CASES = list(cases())


def test_the_table_covers_every_registered_calibrator_and_its_fields():
    package = {tag for tag, cls in registered().items() if cls.__module__.startswith("wavemeter.")}
    assert {documents()[name]["method"] for name, _ in CASES} == package
    keys = {path[-1] for _, path in CASES}
    # every physical expectation names a field some calibrator saves
    assert POSITIVE | NONZERO | NON_NEGATIVE <= keys
    assert len(CASES) > 60


def covered(path, rules) -> bool:
    """Whether a rule names the field at ``path`` (below its section), or every element."""
    dotted = ".".join("*" if isinstance(part, int) else part for part in path[1:])
    return dotted in rules or f"{dotted}.*" in rules


def test_every_number_a_calibrator_saves_has_a_declared_rule():
    """A field added to a calibrator's state without a rule fails here: declare it in the
    class's ``state_rules``."""
    for name, document in documents().items():
        cls = registered()[document["method"]]
        for section, attribute in (
            ("state", "state_rules"),
            ("reading_model", "reading_model_rules"),
        ):
            rules = declared_rules(cls, attribute)
            for path, _ in numeric_fields(document[section], (section,)):
                assert covered(path, rules), f"{name}: {field_name(path)} has no rule"


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return write_test_files(tmp_path_factory.mktemp("ranges"))


def with_field(document: dict, path, value) -> dict:
    changed = json.loads(json.dumps(document))
    node = changed
    for part in path[:-1]:
        node = node[part]
    node[path[-1]] = value
    return changed


def refused_by_every_command(path: Path, calibrator_name: str, key: str, folder: Path) -> None:
    """`info`, `measure` and `evaluate` refuse the calibration file in one line that names
    it and the field; no output file."""
    test = folder / f"{calibrator_name}-test.csv"
    out = folder / "out.csv"
    out.unlink(missing_ok=True)
    commands = (
        ["info", str(path)],
        ["measure", str(path), str(test), "-o", str(out), "--quiet"],
        ["evaluate", str(path), str(test)],
    )
    for arguments in commands:
        code, errors = run(arguments)
        assert code == 2, errors
        assert errors.startswith(f"error: {path}: ") and errors.count("\n") == 1, errors
        assert key in errors and not any(internal in errors for internal in INTERNALS), errors
        assert not out.exists()


def bad_files(folder: Path, name: str, path):
    """(bad value, file, what loading it gave: the calibrator or the FileFormatError) for
    each bad value of the field at ``path``; the file's own checks asserted."""
    document = documents()[name]
    value = document
    for part in path:
        value = value[part]
    key = next(part for part in reversed(path) if isinstance(part, str))
    for bad in BAD_VALUES:
        file = folder / f"{name}-{bad}.wmcal.json"
        file.write_text(json.dumps(with_field(document, path, bad_value(value, bad))))
        try:
            loaded = wm.load_calibration(file)
        except wm.FileFormatError as exc:
            message = str(exc)
            assert message.startswith(f"{file}: ") and key in message, message
            assert not any(internal in message for internal in INTERNALS), message
            yield bad, file, exc
            continue
        assert not must_refuse(key, bad), f"{field_name(path)} = {bad} loaded"
        usable(loaded, name)
        yield bad, file, loaded


IDS = [f"{name}-{field_name(path)}" for name, path in CASES]


@pytest.mark.slow
@pytest.mark.parametrize(("name", "path"), CASES, ids=IDS)
def test_a_bad_number_is_refused_naming_the_field_or_reads(folder, name, path):
    refused = [bad for bad, _, got in bad_files(folder, name, path) if isinstance(got, Exception)]
    assert ALWAYS_REFUSED <= set(refused)


@pytest.mark.slow
@pytest.mark.parametrize(("name", "path"), CASES, ids=IDS)
def test_every_command_refuses_a_bad_number_in_one_line_or_reads_it(folder, name, path):
    """`info`, `measure` and `evaluate` on each bad file: one error line naming the
    calibration file and the field, or (a value the rules let through) exit code 0."""
    key = next(part for part in reversed(path) if isinstance(part, str))
    for _, file, got in bad_files(folder, name, path):
        if isinstance(got, Exception):
            refused_by_every_command(file, name, key, folder)
        else:
            check_commands(file, got, name, folder, refusal_allowed=False)


# ---------------------------------------------------------------------------- the two
@pytest.mark.parametrize("noise_w", [5e-307, 5e293])
def test_a_port_noise_out_of_range_names_the_calibration_file(folder, noise_w):
    """Issue 29: with the maximum-likelihood phase, 5e-307 passed the loader and `info`,
    then `measure` printed a traceback; 5e293 made `measure` blame the data file. Now every
    command names the calibration file and the field (never the data file), and nothing is
    written."""
    assert fitted()["learned"][0].retrieval == "ml"
    document = documents()["learned"]
    noise = document["state"]["port_noise_std_w"]
    path = folder / "noise.wmcal.json"
    changed = with_field(document, ("state", "port_noise_std_w"), [noise_w, *noise[1:]])
    path.write_text(json.dumps(changed))
    with pytest.raises(wm.FileFormatError, match="'port_noise_std_w'") as caught:
        wm.load_calibration(path)
    assert f"got {noise_w!r} (element [0])" in str(caught.value)
    refused_by_every_command(path, "learned", "port_noise_std_w", folder)
    out = folder / "noise-out.csv"
    _, errors = run(["measure", str(path), str(folder / "learned-test.csv"), "-o", str(out)])
    assert "learned-test.csv" not in errors and not out.exists()


def test_the_noise_bounds_follow_the_map_scale(folder):
    """The same relative noise loads at any power scale: map and powers in other units."""
    document = documents()["learned"]
    for scale in (1e-9, 1e3):
        scaled = json.loads(json.dumps(document))
        state, model = scaled["state"], scaled["reading_model"]
        state["map"] = (np.array(state["map"]) * scale).tolist()
        for key in ("noise_std_w", "residual_rms_w"):
            state[key] *= scale
        state["cost_w2"] *= scale**2
        state["port_noise_std_w"] = [value * scale for value in state["port_noise_std_w"]]
        covariance = np.array(state["parameter_covariance"])
        covariance[:-1, :-1] *= scale**2
        covariance[:-1, -1] *= scale
        covariance[-1, :-1] *= scale
        state["parameter_covariance"] = covariance.tolist()
        model["total_power_range_w"] = [value * scale for value in model["total_power_range_w"]]
        path = folder / "scaled.wmcal.json"
        path.write_text(json.dumps(scaled))
        wm.load_calibration(path)

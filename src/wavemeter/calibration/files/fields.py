"""What each number of a calibration file may hold: a declared rule per field, checked on load.

Every calibrator class declares ``state_rules`` for its ``state`` object, and may declare
``diagnostics_rules`` for the records its report presents;
:class:`~wavemeter.calibration.contract.base.BaseCalibrator` declares ``reading_model_rules``
and the common diagnostics'. Each table maps a field path to a rule (or a tuple of rules,
:mod:`~wavemeter.calibration.files.rules`); a subclass adds to or replaces its bases' rules
(:func:`declared_rules`), so a new field is one line. Paths name nested fields with dots and
every element of a list with ``*`` (``"ellipse.amplitude_x"``, ``"handovers.*.ratio"``).
:func:`check_fields` applies them before the state is read: every element finite, of its
sign, within bounds that are absolute (temperatures in K) or relative to a scale of the file
itself (a noise against the map's largest singular value, a delay's standard error against
the delay). A top-level field the file lacks (an older schema) or holds as null is left to
the class's ``_set_state``, which decides whether it may. The bounds and their physics: the
user guide's safety page (numbers of a calibration file).
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Mapping

from ...exceptions import InputError, shown
from .rules import (
    POWER_SCALE_W,
    SPREAD_RELATIVE,
    CovarianceRule,
    FieldRule,
    RecordRule,
    ScaleRule,
    Scales,
    largest_magnitude,
    largest_singular_value,
    rule_table,
    vector_norm,
)

__all__ = [
    "ANGLE_RAD",
    "ANGLE_RULE",
    "CENTER_RANGE_HZ",
    "COST_RULE",
    "CovarianceRule",
    "DELAY_RTOL",
    "DELAY_RULE",
    "DELAY_STD_RULE",
    "FieldRule",
    "MAP_RULE",
    "MAX_FSR_RATIO",
    "MAX_MARGIN_STD",
    "MIN_FSR_HZ",
    "NOISE_DOF_RULE",
    "NOISE_MODEL_RULES",
    "NOISE_RELATIVE",
    "NOISE_RULE",
    "OFFSET_RULE",
    "POWER_SCALE_W",
    "RELATIVE_RATE_PER_K",
    "RESIDUAL_RULE",
    "RecordRule",
    "SPREAD_RELATIVE",
    "ScaleRule",
    "TEMPERATURE_K",
    "TEMPERATURE_RULE",
    "check_fields",
    "check_setting_types",
    "declared_rules",
    "header_scales",
    "largest_magnitude",
    "largest_singular_value",
    "record_number",
    "rule_table",
    "vector_norm",
]

#: centre frequencies a calibration of light may have (Hz): 1 THz (300 um) to 3 PHz
#: (100 nm), wider than the band the column readers accept, so any optical fit loads
CENTER_RANGE_HZ = (1e12, 3e15)
#: smallest FSR (Hz): a delay of 1 ms, 200 km of fibre, beyond any interferometer's arm
MIN_FSR_HZ = 1e3
#: a noise standard deviation against the power scale: float64 rounding of a noiseless
#: (simulated) sweep leaves 1e-16 of it, a real detector far more; a noise 1000 times the
#: fringe hides the fringe a fit found
NOISE_RELATIVE = (1e-18, 1e3)
#: an angle (rad): the fits write (-pi, pi]; two turns either way are accepted
ANGLE_RAD = 4.0 * math.pi
#: chip temperatures (K): from a dilution refrigerator (1 mK) to far beyond any packaged chip
TEMPERATURE_K = (1e-3, 1000.0)
#: a margin in standard deviations (half an FSR over a frequency standard deviation): a
#: noiseless sweep's phase noise is float64 rounding, 1e-16 rad, which gives 1e16; no more
MAX_MARGIN_STD = 1e18
#: an FSR ratio of two stages: the widest optical FSR over the smallest
MAX_FSR_RATIO = CENTER_RANGE_HZ[1] / MIN_FSR_HZ
#: relative thermal rate of an optical delay (1/K): thermo-optic over index plus expansion is
#: 1e-5 to 2e-4 per K for every waveguide and fibre; 1e-3 is five times silicon's
RELATIVE_RATE_PER_K = 1e-3


def header_scales(fsr_hz: float, center_hz: float, span_hz, n_ports: int, n_samples: int):
    """The scales the checked header of a calibration gives its state's rules."""
    width = span_hz[1] - span_hz[0]
    return Scales(
        delay_s=(1.0 / fsr_hz, "the delay 1 / fsr_hz", "s"),
        band_hz=(max(width, fsr_hz), "the larger of the span and the FSR", "Hz"),
        band_phase_rad=(
            math.pi * max(width, fsr_hz) / fsr_hz,
            "the phase across half the band, pi span / FSR",
            "rad",
        ),
        optical_phase_rad=(
            2.0 * math.pi * center_hz / fsr_hz,
            "the optical phase of the delay, 2 pi centre / FSR",
            "rad",
        ),
        readings=(float(n_samples * n_ports), "the numbers of the sweep, n_samples x n_ports", ""),
        samples=(float(n_samples), "the sweep's readings, n_samples", ""),
        last_port=(float(n_ports - 1), "the last port's index, n_ports - 1", ""),
    )


def record_number(
    what: str, unit: str = "", low=None, high=None, integer=False, scale=None
) -> FieldRule:
    """The rule of one number a record must hold (a diagnostics entry a report presents)."""
    return FieldRule(
        what, unit, low, high, scale=scale, integer=integer, required=True, scalar=True
    )


def declared_rules(cls: type, attribute: str) -> dict:
    """The rules a class declares in ``attribute`` with those of its bases (a subclass's
    rule for a field replaces its base's)."""
    rules: dict = {}
    for klass in reversed(cls.__mro__):
        rules.update(klass.__dict__.get(attribute) or {})
    return rules


def _located(node, path: list[str], name: str, required: bool):
    """(name, value) of every field a path names below ``node``; a missing or null one is
    left out, or refused where ``required``."""
    if node is None:
        if required:
            raise InputError(f"field {name!r} is missing")
        return
    if not path:
        yield name, node
        return
    key, rest = path[0], path[1:]
    if key == "*":
        if not isinstance(node, list):
            raise InputError(f"field {name!r} must be a list, got {shown(node, as_in_file=True)}")
        for index, child in enumerate(node):
            if child is None:
                raise InputError(
                    f"field {name!r} must hold no null, got {shown(node, as_in_file=True)}"
                )
            yield from _located(child, rest, f"{name}[{index}]", required)
        return
    if not isinstance(node, dict):
        raise InputError(f"field {name!r} must be an object, got {shown(node, as_in_file=True)}")
    if key in node or required:
        yield from _located(node.get(key), rest, f"{name}.{key}", required)


def _apply(rules: Mapping, document: dict, prefix: str, scales: Scales, scales_only: bool) -> None:
    """Apply the scale rules (``scales_only``) or the others to a part of a file."""
    for path, declared in rules.items():
        first, *rest = path.split(".")
        if document.get(first) is None:
            continue  # the class's _set_state decides whether it may be missing
        for rule in declared if isinstance(declared, tuple) else (declared,):
            if isinstance(rule, ScaleRule) != scales_only:
                continue
            required = getattr(rule, "required", False)
            for name, value in _located(document[first], rest, prefix + first, required):
                if isinstance(rule, CovarianceRule):
                    rule.check(name, value, scales, document)
                else:
                    rule.check(name, value, scales)


def _holds_object(value) -> bool:
    if isinstance(value, dict):
        return True
    return isinstance(value, (list, tuple)) and any(map(_holds_object, value))


def check_setting_types(cls: type, settings: dict) -> None:
    """A file's settings, as the class's ``_params_from_file`` gives them, of the kind of
    the class's defaults: a number where the default is one, a text where it is text, null
    only where the default is, and no JSON object anywhere (the class checks their values).

    Raises
    ------
    InputError
        Naming the setting and what the file holds (as JSON).
    """
    defaults = inspect.signature(cls.__init__).parameters
    for name, value in settings.items():
        default = defaults[name].default if name in defaults else None
        number = isinstance(default, (int, float)) and not isinstance(default, bool)
        if number and (isinstance(value, bool) or not isinstance(value, (int, float))):
            raise InputError(
                f"field 'params.{name}' must be a number, got {shown(value, as_in_file=True)}"
            )
        if isinstance(default, str) and not isinstance(value, str):
            raise InputError(
                f"field 'params.{name}' must be a text, got {shown(value, as_in_file=True)}"
            )
        if value is None and default is not None and name in defaults:
            raise InputError(f"field 'params.{name}' must not be null")
        if _holds_object(value):
            raise InputError(
                f"field 'params.{name}' must hold no object, got {shown(value, as_in_file=True)}"
            )


def check_fields(
    cls: type, scales: Scales, state: dict, reading_model: dict, diagnostics: dict
) -> None:
    """Apply the rules ``cls`` declares to a file's state, reading model and diagnostics.

    The scales come first (the state's, then the reading model's for a class whose state
    sets none), then every other rule.

    Raises
    ------
    InputError
        Naming the first field that breaks its rule, what it holds and what is allowed.
    """
    parts = (
        (declared_rules(cls, "state_rules"), state, ""),
        (declared_rules(cls, "reading_model_rules"), reading_model, "reading_model."),
        (declared_rules(cls, "diagnostics_rules"), diagnostics, "diagnostics."),
    )
    for scales_only in (True, False):
        for rules, document, prefix in parts:
            _apply(rules, document, prefix, scales, scales_only)


# ---------------------------------------------------------------------------- shared rules
#: the learned map (W): its largest singular value is the file's power scale
MAP_RULE = ScaleRule("the map", largest_singular_value, "the map's largest singular value")
#: a detector noise standard deviation (W), positive, against the power scale
NOISE_RULE = FieldRule(
    "a detector noise standard deviation", "W", *NOISE_RELATIVE, scale="power_w", open_low=True
)
#: a residual RMS (W)
RESIDUAL_RULE = FieldRule("a residual RMS", "W", 0.0, SPREAD_RELATIVE, scale="power_w")
#: the fit's cost (W^2): at most the readings' count times the square of a spread
COST_RULE = FieldRule("the fit's cost", "W^2", 0.0, SPREAD_RELATIVE**2, scale="cost_w2")
#: the noise estimate's degrees of freedom: > 2 (a Student factor) and at most one per number
NOISE_DOF_RULE = (
    FieldRule("the noise estimate's degrees of freedom", "", 2.0, open_low=True),
    FieldRule("the noise estimate's degrees of freedom", high=1.0, scale="readings"),
)
#: relative mismatch allowed between a stored delay and 1 / FSR (rounding only)
DELAY_RTOL = 1e-9
#: the delay (s): 1 / fsr_hz, to rounding
DELAY_RULE = FieldRule("the delay", "s", 1.0 - DELAY_RTOL, 1.0 + DELAY_RTOL, scale="delay_s")
#: the delay's standard error (s): a delay known no better than its own size is no calibration
DELAY_STD_RULE = FieldRule("the delay's standard error", "s", 0.0, 1.0, scale="delay_s")
#: an offset or a dark reading of a port (W), against the power scale
OFFSET_RULE = FieldRule(
    "a port's offset", "W", high=SPREAD_RELATIVE, scale="power_w", magnitude=True
)
#: an angle (rad)
ANGLE_RULE = FieldRule("an angle", "rad", high=ANGLE_RAD, magnitude=True)
#: a chip temperature (K)
TEMPERATURE_RULE = FieldRule("a chip temperature", "K", *TEMPERATURE_K)
#: the noise model of a learned map (its fit's cost, residual, per-port noise and their
#: degrees of freedom), shared by the methods that estimate it
NOISE_MODEL_RULES = rule_table(
    {
        "cost_w2": COST_RULE,
        "residual_rms_w": RESIDUAL_RULE,
        "noise_std_w": NOISE_RULE,
        "port_noise_std_w": NOISE_RULE,
        "noise_dof": NOISE_DOF_RULE,
    }
)

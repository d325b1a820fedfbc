"""The kinds of rule a number of a calibration file obeys, and the scales they compare with.

:class:`FieldRule` bounds every element of a numeric field (absolutely, or relative to a
scale of the file); :class:`ScaleRule` makes a field a scale (the map's largest singular
value is the power scale); :class:`CovarianceRule` checks a parameter covariance;
:class:`RecordRule` the shape of a record (an object, a list, a text, a flag). Each names
the field, what it holds and what is allowed. Which field obeys which rule:
:mod:`~wavemeter.calibration.files.fields`.
"""

from __future__ import annotations

import types
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from ...exceptions import InputError, shown

__all__ = [
    "CovarianceRule",
    "FieldRule",
    "POWER_SCALE_W",
    "RecordRule",
    "SPREAD_RELATIVE",
    "ScaleRule",
    "Scales",
    "largest_magnitude",
    "largest_singular_value",
    "rule_table",
    "vector_norm",
]

#: a power scale (W, or the readings' linear unit): 1 aW to 1 GW, beyond any photodetector
#: both ways (and ADC counts of 2^24) while squares and products stay far inside float64
POWER_SCALE_W = (1e-18, 1e9)
#: offsets, dark readings, residuals and parameter standard errors against the power scale:
#: beyond 1000 times the fringe the fitted model says nothing of the readings
SPREAD_RELATIVE = 1e3


def _scaled(array: np.ndarray) -> tuple[np.ndarray, float]:
    """``array / m`` and ``m = max |array|`` (1 for zeros): norms without overflow."""
    largest = float(np.max(np.abs(array)))
    return (array / largest, largest) if largest > 0 else (array, 1.0)


def largest_singular_value(array: np.ndarray) -> float | None:
    """The largest singular value of a matrix (of the first of a stack); None for another shape."""
    if array.ndim == 3 and array.shape[0] > 0:
        array = array[0]
    if array.ndim != 2 or 0 in array.shape:
        return None
    unit, largest = _scaled(array)
    return float(np.linalg.svd(unit, compute_uv=False)[0]) * largest


def largest_magnitude(array: np.ndarray) -> float | None:
    """The largest absolute value of a number or a vector; None for another shape."""
    return float(np.max(np.abs(array))) if array.ndim <= 1 else None


def vector_norm(array: np.ndarray) -> float | None:
    """The Euclidean norm of a vector; None for another shape."""
    if array.ndim != 1:
        return None
    unit, largest = _scaled(array)
    return float(np.linalg.norm(unit)) * largest


class Scales(dict):
    """Scales the relative rules compare with: name -> (value, what it is, unit)."""

    def value(self, name: str | None) -> float | None:
        return None if name is None or name not in self else self[name][0]

    def text(self, name: str) -> str:
        value, what, unit = self[name]
        return f"{what}, {value:.4g}{' ' + unit if unit else ''}"


def _power_scales(scales: Scales) -> None:
    """The derived power scales once ``power_w`` is known."""
    power, what, _ = scales["power_w"]
    scales["power_w2"] = (power**2, f"the square of {what}", "W^2")
    scales["cost_w2"] = (
        power**2 * scales.value("readings"),
        f"n_samples x n_ports x the square of {what}",
        "W^2",
    )


def _numbers(name: str, value) -> np.ndarray:
    """A field's value as a float array, or an InputError naming it."""
    problem = InputError(
        f"field {name!r} must hold numbers only, got {shown(value, as_in_file=True)}"
    )
    if isinstance(value, (bool, str)) or isinstance(value, dict):
        raise problem
    try:
        array = np.asarray(value)
        if array.dtype.kind == "O":  # integers beyond int64, or mixed content
            array = array.astype(float)
    except (ValueError, TypeError, OverflowError) as exc:
        raise problem from exc
    if array.dtype.kind not in "iuf":
        raise problem
    array = array.astype(float)
    if not np.all(np.isfinite(array)):
        kind = "be a finite number" if array.ndim == 0 else "hold finite numbers only"
        raise InputError(f"field {name!r} must {kind}, got {shown(value, as_in_file=True)}")
    return array


def _first_outside(array: np.ndarray, inside: np.ndarray) -> str:
    """``value`` (and its index in an array) of the first element not ``inside``."""
    index = np.flatnonzero(~inside.ravel())[0]
    value = shown(float(array.ravel()[index]), as_in_file=True)
    if array.ndim == 0:
        return value
    where = ", ".join(str(int(at)) for at in np.unravel_index(index, array.shape))
    return f"{value} (element [{where}])"


@dataclass(frozen=True)
class FieldRule:
    """What a numeric field may hold: each element in ``[low, high]`` times a scale.

    Parameters
    ----------
    what : str
        The quantity in words (``"a detector noise standard deviation"``).
    unit : str
        Its unit (``"W"``; ``""`` for a pure number).
    low, high : float or None
        Bounds, in units of ``scale`` (absolute when ``scale`` is None); None: unbounded.
    scale : str or None
        Name of a scale of the file (:func:`header_scales`, ``power_w``, ``power_w2``,
        ``cost_w2``). When the file gives none (a file without a map or a reading model),
        only the bounds' signs are kept.
    open_low : bool
        ``> low`` rather than ``>= low``.
    magnitude : bool
        The bounds apply to the absolute value.
    integer : bool
        Whole numbers only.
    choices : tuple of float
        The only values allowed (``(-1, 1)``), instead of bounds.
    required : bool
        A missing or null field is an error (records the loader does not otherwise read).
    scalar : bool
        One number, not a list (a record's; the class's ``_set_state`` checks the shapes of
        its state).
    """

    what: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    scale: str | None = None
    open_low: bool = False
    magnitude: bool = False
    integer: bool = False
    choices: tuple = ()
    required: bool = False
    scalar: bool = False

    def _bounds(self, scales: Scales) -> tuple[float | None, float | None, str]:
        """Absolute bounds and how to say them."""
        factor = scales.value(self.scale) if self.scale else 1.0
        if factor is None:  # the file gives no scale: only the signs of the bounds
            low = None if self.low is None else (0.0 if self.low >= 0 else None)
            return low, None, ""
        low = None if self.low is None else self.low * factor
        high = None if self.high is None else self.high * factor
        if not self.scale:
            return low, high, ""
        relative = " to ".join(f"{bound:g}" for bound in (self.low, self.high) if bound is not None)
        return low, high, f" ({relative} times {scales.text(self.scale)})"

    def _quantity(self, value: float, digits: int = 4) -> str:
        return f"{value:.{digits}g}{' ' + self.unit if self.unit else ''}"

    def check(self, name: str, value, scales: Scales) -> None:
        """Raise an InputError naming ``name`` unless every element is allowed."""
        array = _numbers(name, value)
        if self.scalar and array.ndim:
            raise InputError(
                f"field {name!r} ({self.what}) must be one number, got "
                f"{shown(value, as_in_file=True)}"
            )
        if self.integer and not np.all(array == np.round(array)):
            raise InputError(
                f"field {name!r} ({self.what}) must hold whole numbers, got "
                f"{_first_outside(array, array == np.round(array))}"
            )
        if self.choices:
            inside = np.isin(array, self.choices)
            if not inside.all():
                raise InputError(
                    f"field {name!r} ({self.what}) must be one of "
                    f"{', '.join(map(str, self.choices))}, got {_first_outside(array, inside)}"
                )
            return
        low, high, relative = self._bounds(scales)
        values = np.abs(array) if self.magnitude else array
        inside = np.ones(array.shape, dtype=bool)
        allowed = []
        # bounds a rounding apart (a delay that must be 1 / FSR) are shown to 12 digits
        close = low is not None and high is not None and high - low < 1e-6 * abs(high)
        digits = 12 if close else 4
        if low is not None:
            inside &= values > low if self.open_low else values >= low
            allowed.append(f"{'>' if self.open_low else '>='} {self._quantity(low, digits)}")
        if high is not None:
            inside &= values <= high
            allowed.append(f"<= {self._quantity(high, digits)}")
        if not inside.all():
            subject = "in magnitude " if self.magnitude else ""
            raise InputError(
                f"field {name!r} ({self.what}) must be {subject}{' and '.join(allowed)}"
                f"{relative}, got {_first_outside(array, inside)}"
            )


@dataclass(frozen=True)
class ScaleRule:
    """A field that sets a scale of the file (the map's largest singular value as
    ``power_w``), itself within absolute bounds; a scale already set is kept.

    Parameters
    ----------
    what : str
        The quantity in words.
    reduce : callable
        Float array -> the scale, or None for a shape ``_set_state`` will refuse.
    scale_what : str
        What the scale is, in words (``"the map's largest singular value"``).
    unit : str
        The scale's unit.
    bounds : (float, float)
        Where the scale must lie.
    name : str
        The scale it sets.
    """

    what: str
    reduce: Callable[[np.ndarray], float | None]
    scale_what: str
    unit: str = "W"
    bounds: tuple[float, float] = POWER_SCALE_W
    name: str = "power_w"

    def check(self, name: str, value, scales: Scales) -> None:
        array = _numbers(name, value)
        scale = self.reduce(array) if array.size else None
        if scale is None or self.name in scales:
            return
        low, high = self.bounds
        if not low <= scale <= high:
            raise InputError(
                f"field {name!r} ({self.what}) must give {self.scale_what} between {low:g} "
                f"and {high:g} {self.unit}, got {scale:.4g} {self.unit}"
            )
        scales[self.name] = (scale, self.scale_what, self.unit)
        if self.name == "power_w":
            _power_scales(scales)


@dataclass(frozen=True)
class CovarianceRule:
    """A parameter covariance: symmetric, variances >= 0, correlations within +-1, the
    map's parameters (first) with standard errors within ``SPREAD_RELATIVE`` times the
    power scale, each nonlinear parameter (last) within its own bound.

    Parameters
    ----------
    tail : tuple of (str, str or None, float)
        Per nonlinear parameter, in order: its name, a scale (None: absolute), and the
        largest standard error in units of that scale.
    tail_repeats : str or None
        A state field whose integer value repeats ``tail`` (the wide band's phase orders).
    """

    tail: tuple = ()
    tail_repeats: str | None = None
    what: str = "the covariance of the fitted parameters"

    def _tail(self, state: dict) -> tuple:
        count = state.get(self.tail_repeats) if self.tail_repeats else 1
        if isinstance(count, bool) or not isinstance(count, (int, float)) or not 0 <= count < 100:
            return ()
        return tuple(
            (f"{name} {index + 1}" if self.tail_repeats else name, scale, factor)
            for index in range(int(count))
            for name, scale, factor in self.tail
        )

    def check(self, name: str, value, scales: Scales, state: dict) -> None:
        matrix = _numbers(name, value)
        if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1] or matrix.size == 0:
            return  # the class's _set_state names the shape it needs
        variance = np.diag(matrix)
        if np.any(variance < 0):
            raise InputError(
                f"field {name!r} ({self.what}) must have variances >= 0 on its diagonal, got "
                f"{_first_outside(variance, variance >= 0)}"
            )
        std = np.sqrt(variance)
        tail = self._tail(state)
        entries = [("a map entry", "power_w", SPREAD_RELATIVE)] * (std.size - len(tail))
        for index, (label, scale, factor) in enumerate([*entries, *tail][-std.size :]):
            limit = 1.0 if scale is None else scales.value(scale)
            if limit is not None and std[index] > factor * limit:
                of = "" if scale is None else f" times {scales.text(scale)}"
                raise InputError(
                    f"field {name!r} ({self.what}) gives {label} (parameter {index}) a standard "
                    f"error of {std[index]:.4g}, more than {factor:g}{of}: no calibration is "
                    "that uncertain"
                )
        # a bound beyond float64 (std of 1e160, a file without a power scale) is infinite,
        # which every finite entry keeps
        with np.errstate(over="ignore", invalid="ignore"):
            bound = np.outer(std, std)
            tolerance = 1e-6 * bound + np.finfo(float).tiny
            broken = np.abs(matrix - matrix.T) > tolerance
            broken |= np.abs(matrix) > bound + tolerance
        if np.any(broken):
            raise InputError(
                f"field {name!r} ({self.what}) must be symmetric with correlations within "
                "+-1 (a covariance matrix)"
            )


@dataclass(frozen=True)
class RecordRule:
    """The shape of a part of a record the loader does not otherwise read (a diagnostics
    record a report presents): ``kind`` is ``"object"``, ``"list"`` (of at least
    ``min_items``), ``"text"``, ``"texts"`` (a list of texts) or ``"flag"`` (true or false).
    """

    what: str
    kind: str
    required: bool = True
    min_items: int = 0

    def check(self, name: str, value, scales: Scales) -> None:
        kinds = {
            "object": isinstance(value, dict),
            "list": isinstance(value, list) and len(value) >= self.min_items,
            "text": isinstance(value, str),
            "texts": isinstance(value, list) and all(isinstance(item, str) for item in value),
            "flag": isinstance(value, bool),
        }
        if not kinds[self.kind]:
            wanted = {
                "object": "an object",
                "list": f"a list of at least {self.min_items} entries",
                "text": "a text",
                "texts": "a list of texts",
                "flag": "true or false",
            }[self.kind]
            raise InputError(
                f"field {name!r} ({self.what}) must be {wanted}, got "
                f"{shown(value, as_in_file=True)}"
            )


def rule_table(rules: dict) -> Mapping:
    """A class's table of rules (field path -> rule or tuple of rules), read-only."""
    return types.MappingProxyType(dict(rules))

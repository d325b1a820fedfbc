"""Numbers of a loaded calibration state: a finite number within its range, a finite array
of its shape, each refused with the field's name."""

from __future__ import annotations

import math

import numpy as np

from ...exceptions import InputError, shown

__all__ = ["is_real", "state_float", "state_array"]


def is_real(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def state_float(
    state: dict,
    key: str,
    *,
    minimum: float | None = None,
    open_minimum: bool = False,
    maximum: float | None = None,
) -> float:
    """A finite number from a loaded state, within ``[minimum, maximum]`` when given.

    Raises
    ------
    InputError
        Naming the field, when it is missing, not a number, not finite or out of range.
    """
    if key not in state:
        raise InputError(f"field {key!r} is missing")
    value = state[key]
    if not is_real(value) or not math.isfinite(value):
        raise InputError(
            f"field {key!r} must be a finite number, got {shown(value, as_in_file=True)}"
        )
    value = float(value)
    if minimum is not None and (value < minimum or (open_minimum and value == minimum)):
        relation = ">" if open_minimum else ">="
        raise InputError(f"field {key!r} must be {relation} {minimum:g}, got {value!r}")
    if maximum is not None and value > maximum:
        raise InputError(f"field {key!r} must be <= {maximum:g}, got {value!r}")
    return value


def state_array(state: dict, key: str, shape: tuple) -> np.ndarray:
    """A finite float array of ``shape`` (None: any length) from a loaded state.

    Raises
    ------
    InputError
        Naming the field, when it is missing, ragged, not numeric, of another shape or
        holds NaN or inf.
    """
    if key not in state:
        raise InputError(f"field {key!r} is missing")
    try:
        array = np.asarray(state[key])
    except (ValueError, TypeError) as exc:
        raise InputError(
            f"field {key!r} must be nested lists of numbers of equal lengths, got "
            f"{shown(state[key], as_in_file=True)}"
        ) from exc
    if array.dtype.kind not in "iuf":
        raise InputError(
            f"field {key!r} must hold numbers only, got {shown(state[key], as_in_file=True)}"
        )
    matches = array.ndim == len(shape) and all(
        size is None or size == actual for size, actual in zip(shape, array.shape, strict=True)
    )
    if not matches or not np.all(np.isfinite(array)):
        sizes = " x ".join("any" if size is None else str(size) for size in shape)
        raise InputError(f"field {key!r} must be {sizes} finite numbers, got shape {array.shape}")
    return array.astype(float)

"""One reading of the learned family's pseudo-inverse map, in plain floats.

:func:`pinv_row_reader` is what
:meth:`~wavemeter.calibration.methods.learned_reading.LearnedReadingMixin._row_reader` puts
in front of the generic one-row path for a calibration that reads with the pseudo-inverse
and whose phase is the delay's alone: the pseudo-inverse rows, offsets, noise weights,
flag thresholds and the covariance are taken once, and a reading that is finite, lit and
given no per-reading input is read with Python floats (the same arithmetic as
:meth:`readout`'s arrays, one reading at a time: frequency, its standard deviation, every
flag bit); every other reading, and the exact ``OFF_MODEL`` test where the screen cannot
decide, go the generic way: ~20 us a reading instead of ~180 us (Table 1, 3 ports).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..contract.flags import (
    NO_LIGHT_FRACTION,
    POWER_RANGE_FACTOR,
    SPAN_MARGIN_STD,
    UNCHECKED_OFFSET_FACTOR,
    ReadingFlag,
)
from ..contract.records import StreamReading
from ..contract.streaming import SCREEN_MARGIN

__all__ = ["pinv_row_reader"]

_INVALID = int(ReadingFlag.INVALID)
_POWER_RANGE = int(ReadingFlag.POWER_RANGE)
_OUTSIDE_SPAN = int(ReadingFlag.OUTSIDE_SPAN)
_OFF_MODEL = int(ReadingFlag.OFF_MODEL)
_SQRT2 = math.sqrt(2.0)
_NO_EXTRAS: dict = {}


def _light_limits(calibration) -> tuple[float, float, float] | None:
    """Total powers (W) below which a reading is dark (``INVALID``), and outside which it
    is ``POWER_RANGE``, as :func:`~wavemeter.calibration.contract.flags.power_flags`."""
    if calibration.total_power_range_w_ is None:
        return None
    low, high = (float(v) for v in calibration.total_power_range_w_)
    factor = POWER_RANGE_FACTOR if calibration._offsets_known() else UNCHECKED_OFFSET_FACTOR
    return NO_LIGHT_FRACTION * low, low / factor, high * factor


def pinv_row_reader(calibration, generic: Callable) -> Callable:
    """``read_row(row, inputs) -> (record, reason)`` of a learned calibration with the
    pseudo-inverse retrieval and a delay-only phase; ``generic`` reads what it does not.

    Parameters
    ----------
    calibration : Calibrator
        Fitted; its state is taken now.
    generic : callable
        The generic ``read_row`` (:meth:`StreamMixin._row_reader`).
    """
    ports = calibration.n_ports_
    offset = calibration._reading_offset_w()
    shift = [float(v) for v in offset] if offset.any() else None
    inverse_0, inverse_1 = (calibration.map_pinv_[row].tolist() for row in (0, 1))
    matrix = calibration.map_
    image_rows = matrix.tolist()  # image_j = u . A_j
    noise = np.broadcast_to(np.asarray(calibration.port_noise_std_w_, dtype=float), (ports,))
    sigma = noise.tolist()
    weighted_rows = image_rows
    if np.ndim(calibration.port_noise_std_w_) != 0:  # source_power_ratio's weights
        weighted_rows = (matrix / noise[:, None] ** 2).tolist()
    center = float(calibration.center_hz_)
    per_rad = float(calibration._hz_per_rad())
    covariance = calibration.parameter_covariance_
    with_offsets = covariance is not None and calibration._map_columns() == 4
    delay = float(calibration.delay_s_)
    dof = calibration.noise_dof_
    student = None
    if dof > 2:
        from ...model.uncertainty import student_factor

        student = student_factor(dof)
    span = tuple(float(v) for v in calibration.span_hz_) if calibration._partial_span() else None
    limits = _light_limits(calibration)
    learned = calibration._off_model_learned()
    screen = calibration._off_model_threshold() * (1.0 - SCREEN_MARGIN)
    pinv_pairs = list(zip(inverse_0, inverse_1, strict=True))
    inf = math.inf
    atan2, cos, sin, sqrt = math.atan2, math.cos, math.sin, math.sqrt

    def read_row(row, inputs: dict):
        if inputs["coarse_hz"] is not None or inputs["temperature_k"] is not None:
            return generic(row, inputs)
        try:
            raw = row.tolist()
            usual = len(raw) == ports and 0.0 < sum(raw) < inf
        except (AttributeError, TypeError):  # not an array of numbers
            usual = False
        if not usual:  # not (n,) finite numbers with light: the generic way says why
            return generic(row, inputs)
        r = raw if shift is None else [p - o for p, o in zip(raw, shift, strict=True)]
        flags = 0
        if limits is not None:
            total = sum(r)
            if total < limits[0]:
                flags = _INVALID
            if total < limits[1] or total > limits[2]:
                flags |= _POWER_RANGE
        x_1 = sum([a * p for a, p in zip(inverse_0, r, strict=True)])
        x_2 = sum([a * p for a, p in zip(inverse_1, r, strict=True)])
        phase = atan2(x_2, x_1)
        frequency = center + phase * per_rad
        radius2 = x_1 * x_1 + x_2 * x_2
        gradient = [(x_1 * b - x_2 * a) / radius2 for a, b in pinv_pairs]
        phase_std = sqrt(sum([(g * s) ** 2 for g, s in zip(gradient, sigma, strict=True)]))
        variance = (phase_std * per_rad) ** 2
        c, s = cos(phase), sin(phase)
        u = (c, s, _SQRT2)
        image = [u[0] * m[0] + u[1] * m[1] + u[2] * m[2] for m in image_rows]
        weighted = image
        if weighted_rows is not image_rows:
            weighted = [u[0] * m[0] + u[1] * m[1] + u[2] * m[2] for m in weighted_rows]
        power = sum([w * p for w, p in zip(weighted, r, strict=True)]) / sum(
            [w * i for w, i in zip(weighted, image, strict=True)]
        )
        if covariance is not None:
            objects = [power * c, power * s, power * _SQRT2]
            if with_offsets:
                objects.append(1.0)
            along = [-(g * x) * per_rad for g in gradient for x in objects]
            along.append(-phase * per_rad / delay)
            vector = np.array(along)
            variance = variance + float(vector @ covariance @ vector)
        if student is None:
            std = inf
        else:
            std = sqrt(variance * student**2 + 0.0)
        if not flags & _INVALID:
            if span is not None:
                margin = SPAN_MARGIN_STD * std
                if frequency < span[0] - margin or frequency > span[1] + margin:
                    flags |= _OUTSIDE_SPAN
            if _off_model(r, power, image, phase):
                flags |= _OFF_MODEL
        return StreamReading(frequency, std, flags, _NO_EXTRAS), None

    def _off_model(r, power, image, phase) -> bool:
        """The ``OFF_MODEL`` screen at the retrieved phase (the exact test beyond it)."""
        if not learned:
            distance = sum(
                [((p - power * i) / s) ** 2 for p, i, s in zip(r, image, sigma, strict=True)]
            )
            if distance <= screen:
                return False
            return bool(calibration._off_model(np.array([r]), None)[0])
        return bool(calibration._off_model_remaining(np.array([r]), matrix, np.array([phase]))[0])

    return read_row

"""A record of readings measured as one frequency series, for a frequency-noise analysis.

:func:`measure_series` reads a file of port readings in chunks
(:func:`~wavemeter.io.iter_readings`), turns each chunk into frequency with the
calibration (the chunk measurement of :func:`~wavemeter.jobs.measure_file`) and keeps only
the frequency of each reading, 8 bytes per reading: the series a noise analysis
(:func:`wavemeter.analysis.frequency_noise`) needs whole. Along the way it keeps the RMS of
the readings' own standard deviations (the meter's noise floor), the counts of readings
excluded, and the sampling rate.

Readings excluded (NaN in the series, counted by flag): those the reader found invalid
(NaN, sentinels, no light) and those the calibration flags ``INVALID``, ``OFF_MODEL`` (the
reading is improbably far from the calibrated model: a glitch, a mode hop, a stray
reflection) or ``ORDER_AMBIGUOUS`` (its fringe order may be wrong: off by whole FSRs).
Such a reading's frequency may be off by far more than its standard deviation, and one of
them spoils a power spectrum. Readings flagged ``OUTSIDE_SPAN``, ``POWER_RANGE`` or
``TEMPERATURE_RANGE`` are kept and counted: the calibration is extrapolated there, which
distorts the frequency smoothly and slightly (a scale error), not reading by reading.

A calibration that reads the frequency modulo its FSR gets its series unwrapped
(:mod:`wavemeter.jobs.noise_unwrap`). The sampling rate is given (``rate_hz``) or taken
from a time column whose steps are checked for uniform sampling
(:mod:`wavemeter.jobs.noise_clock`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..calibration.contract.flags import ReadingFlag
from ..exceptions import InputError
from ..io import ColumnRequest, ReadingStream, iter_readings
from ..io.streaming import CHUNK_ROWS
from ..validation import check_positive
from .measure import ChunkMeasurement
from .noise_clock import TIME_JITTER_TOLERANCE, Clock
from .noise_unwrap import Unwrapper
from .readings import check_reading_options, check_readings

__all__ = [
    "measure_series",
    "NoiseSeries",
    "EXCLUDED_FLAGS",
    "reads_modulo_fsr",
]

#: flags that exclude a reading from the series (its frequency may be off by far more
#: than its standard deviation); the other flags are counted, the readings kept
EXCLUDED_FLAGS = ReadingFlag.INVALID | ReadingFlag.OFF_MODEL | ReadingFlag.ORDER_AMBIGUOUS


@dataclass(frozen=True)
class NoiseSeries:
    """A record of readings as one frequency series (what :func:`measure_series` made).

    Attributes
    ----------
    source : Path
        The readings file.
    frequency_hz : ndarray, shape (N,)
        Frequency of each reading in file order (Hz), unwrapped when ``unwrapped``; NaN
        where the reading was excluded.
    rate_hz : float
        Sampling rate (Hz): given, or from the time column.
    meter_std_hz : float or None
        RMS over the readings used of each reading's standard deviation (Hz), the meter's
        own noise; None when the calibration gives none.
    fsr_hz : float
        The calibration's FSR (Hz) (of the finest stage of a cascade): the delay the
        readings average over is ``1 / fsr_hz``.
    scale_rel_std : float
        Relative standard deviation of the calibration's frequency scale, ``delay_std_s_ /
        delay_s_`` (0 when the calibration states none): a drift's uncertainty grows with it.
    unwrapped : bool
        Whether the series was unwrapped with period ``fsr_hz`` (the calibration reads
        modulo its FSR).
    rows : int
        Readings in the file (N).
    excluded : int
        Readings excluded (NaN in ``frequency_hz``).
    flagged : int
        Readings with any flag (excluded or not).
    excluded_counts : dict of str to int
        Excluded readings with each reason: ``INVALID`` (also those the reader refused),
        ``OFF_MODEL``, ``ORDER_AMBIGUOUS``; a reading may have several (reasons none has
        are left out).
    flag_counts : dict of str to int
        Readings with each flag bit, excluded or not, by bit name (as ``measure`` counts
        them; readings the reader refused count as ``INVALID``).
    ambiguous_steps : int
        Steps between consecutive usable readings over ``AMBIGUOUS_STEP_FSR`` of the FSR
        (counted only when unwrapping).
    time_column : str or None
        The time column the rate came from.
    invalid_examples : list of str
        The first rows the reader refused, with their reasons.
    warnings : tuple of Warning
        The warnings the measurement gave (each once), also issued.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.io import write_table
    >>> from wavemeter.jobs import measure_series
    >>> from wavemeter.simulation import laser_frequency_hz
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(device.powers(f_hz, 1e-3, 5e-7, rng=1), f_hz)
    >>> rate_hz = 1e6
    >>> h0 = 1e10  # Hz^2/Hz: a free-running laser that wanders 70 MHz between readings
    >>> laser_hz = laser_frequency_hz(4096, rate_hz, center_hz=f_hz.mean(), white_fm_hz2_per_hz=h0,
    ...     rng=3)
    >>> readings = device.powers(laser_hz, power_w=1e-3, noise_w=5e-7, rng=4)
    >>> path = Path(tempfile.mkdtemp()) / "laser.csv"
    >>> write_table(path, {f"p{k + 1}_w": readings[:, k] for k in range(3)})
    >>> series = measure_series(cal, path, rate_hz=rate_hz)
    >>> print(f"{series.rate_hz / 1e6:.0f} MHz rate, meter std {series.meter_std_hz / 1e6:.0f} MHz")
    1 MHz rate, meter std 13 MHz
    >>> series.frequency_hz.shape, series.flag_counts
    ((4096,), {})
    """

    source: Path
    frequency_hz: np.ndarray
    rate_hz: float
    meter_std_hz: float | None
    fsr_hz: float
    scale_rel_std: float
    unwrapped: bool
    rows: int
    excluded: int
    flagged: int = 0
    excluded_counts: dict[str, int] = field(default_factory=dict)
    flag_counts: dict[str, int] = field(default_factory=dict)
    ambiguous_steps: int = 0
    time_column: str | None = None
    invalid_examples: list[str] = field(default_factory=list)
    warnings: tuple[Warning, ...] = ()


def reads_modulo_fsr(calibration, coarse_column: str | None, coarse_hz: float | None) -> bool:
    """Whether a calibration's readings are its frequency modulo its FSR: one
    interferometer's (no coarse input, not absolute), or a calibration that picks the
    window or order from one coarse frequency for every reading."""
    if calibration.absolute_frequency:
        return False
    if "coarse_hz" not in calibration.requires:
        return True
    return coarse_column is None and coarse_hz is not None


def _scale_rel_std(calibration) -> float:
    """The relative standard error of the calibrated FSR (that of the frequency scale), as
    the calibration states it; 0 where it states none."""
    fsr = calibration.summary().values["fsr_hz"]
    return float(fsr.stderr / fsr.value) if fsr.stderr else 0.0


def _open(readings, request, chunk_rows, time_column, calibration, temperature_k):
    """The stream of readings, with the time column among its kept columns."""
    if isinstance(readings, ReadingStream):
        if time_column is not None and time_column not in readings.kept:
            raise InputError(
                f"{readings.source}: the time column {time_column!r} must be among the kept "
                "columns of a stream opened beforehand (request.keep)",
                parameter="time_column",
            )
        return readings
    request = request or ColumnRequest()
    if time_column is not None and time_column not in request.keep:
        request = dataclasses.replace(request, keep=(*request.keep, time_column))
    thermal = "temperature_k" in calibration.requires
    return iter_readings(
        readings,
        request,
        chunk_rows=chunk_rows,
        allow_invalid=True,
        find_temperature=thermal and temperature_k is None,
    )


def measure_series(
    calibration,
    readings,
    *,
    request: ColumnRequest | None = None,
    rate_hz: float | None = None,
    time_column: str | None = None,
    chunk_rows: int = CHUNK_ROWS,
    coarse_hz: float | None = None,
    temperature_k: float | None = None,
    progress: Callable | None = None,
) -> NoiseSeries:
    """Measure a file of port readings as one frequency series, a chunk at a time.

    Parameters
    ----------
    calibration : BaseCalibrator
        A fitted calibration.
    readings : str, Path or ReadingStream
        The readings file (``"-"``: standard input), or one opened with
        :func:`~wavemeter.io.iter_readings` with ``allow_invalid=True`` and the time
        column kept (not yet iterated; ``request`` and ``chunk_rows`` are then those it
        was opened with).
    request : ColumnRequest, optional
        Columns chosen by the user (ports, power unit, coarse and temperature columns).
    rate_hz : float, optional
        Sampling rate (Hz). Give it, or ``time_column``, or both (they must agree).
    time_column : str, optional
        Column with the time of each reading (unit from its name, else seconds).
    chunk_rows : int
        Rows read and measured at a time.
    coarse_hz : float, optional
        Coarse frequency (Hz) of every reading, for a calibration that needs one and a
        file without a coarse column.
    temperature_k : float, optional
        Chip temperature (K) of every reading, for a calibration that needs it, instead
        of the file's temperature column.
    progress : callable, optional
        ``progress(description, total, unit=...)`` returning a context manager that
        yields ``advance(steps)`` (as :func:`wavemeter.progress.progress_bar`). None:
        silent.

    Returns
    -------
    NoiseSeries

    Raises
    ------
    InputError
        No rate and no time column; a rate that is not a positive number; a time column
        that is missing, holds text or a missing time, does not increase, has a gap or
        is not uniform, or disagrees with the rate given; no usable reading; and what
        :func:`~wavemeter.io.iter_readings` and the calibration refuse.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.io import write_table
    >>> from wavemeter.jobs import measure_series
    >>> from wavemeter.simulation import laser_frequency_hz
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(device.powers(f_hz, 1e-3, 5e-7, rng=1), f_hz)
    >>> rate_hz = 1e6
    >>> h0 = 1e10  # Hz^2/Hz: a free-running laser that wanders 70 MHz between readings
    >>> laser_hz = laser_frequency_hz(4096, rate_hz, center_hz=f_hz.mean(), white_fm_hz2_per_hz=h0,
    ...     rng=3)
    >>> readings = device.powers(laser_hz, power_w=1e-3, noise_w=5e-7, rng=4)
    >>> path = Path(tempfile.mkdtemp()) / "laser.csv"
    >>> write_table(path, {f"p{k + 1}_w": readings[:, k] for k in range(3)})
    >>> series = measure_series(cal, path, rate_hz=rate_hz)
    >>> series.rows, series.excluded, series.unwrapped
    (4096, 0, True)

    The series follows the laser to the meter's noise (14 MHz per reading):

    >>> error_hz = series.frequency_hz - laser_hz
    >>> print(f"{np.std(error_hz) / 1e6:.0f} MHz")
    14 MHz
    """
    rate_hz = None if rate_hz is None else check_positive("rate_hz", rate_hz)
    if rate_hz is None and time_column is None:
        raise InputError(
            "no sampling rate: give the rate of the readings (rate_hz) or the column with "
            "their time stamps (time_column)",
            parameter="rate_hz",
        )
    check_reading_options(calibration, coarse_hz=coarse_hz, temperature_k=temperature_k)
    stream = _open(readings, request, chunk_rows, time_column, calibration, temperature_k)
    ports_given = request is not None and request.ports is not None
    check_readings(
        calibration,
        stream,
        coarse_hz=coarse_hz,
        temperature_k=temperature_k,
        ports_given=ports_given,
    )
    offered = "frequency_std" in calibration.capabilities
    measured = ChunkMeasurement(calibration, offered, coarse_hz, temperature_k, phase=False)
    modulo = reads_modulo_fsr(calibration, stream.coarse_column, coarse_hz)
    fsr_hz = float(calibration.fsr_hz_)
    unwrap = Unwrapper(fsr_hz) if modulo else None
    clock = None if time_column is None else Clock(time_column, stream.source)
    parts: list[np.ndarray] = []
    flags_seen = np.zeros(len(ReadingFlag), dtype=np.int64)
    variance_sum, variance_count, flagged = 0.0, 0, 0
    total, unit = stream.progress_total
    bar = progress(f"measuring {stream.source}", total, unit=unit) if progress else None
    with contextlib.ExitStack() as stack:
        advance = stack.enter_context(bar) if bar is not None else None
        done = 0
        for table in stream:
            if clock is not None:
                clock.add(table)
            columns = measured.chunk(table)
            flags = columns["flags"]
            flags_seen += [np.count_nonzero(flags & bit) for bit in ReadingFlag]
            flagged += int(np.count_nonzero(flags))
            frequency = columns["frequency_hz"]
            used = (flags & int(EXCLUDED_FLAGS)) == 0
            frequency[~used] = np.nan
            if offered:
                std = columns["frequency_std_hz"][used]
                std = std[np.isfinite(std)]
                variance_sum += float(np.sum(std**2))
                variance_count += std.size
            if unwrap is not None:
                unwrap(frequency, table)
            parts.append(frequency)
            if advance is not None:
                advance(stream.progress - done)
            done = stream.progress
    frequency_hz = np.concatenate(parts) if parts else np.empty(0)
    counts = {bit.name: int(count) for bit, count in zip(ReadingFlag, flags_seen, strict=True)}
    excluded = int(np.count_nonzero(np.isnan(frequency_hz)))
    if excluded == frequency_hz.size:
        reasons = ", ".join(
            f"{bit.name} {counts[bit.name]}" for bit in EXCLUDED_FLAGS if counts[bit.name]
        )
        raise InputError(
            f"{stream.source}: no usable reading: all {frequency_hz.size} readings are "
            f"excluded{f' ({reasons})' if reasons else ''}"
            + (f", first: {stream.describe_invalid(3)}" if stream.invalid_rows else "")
            + "; check that the readings belong to this calibration (ports, power, device)",
        )
    if clock is not None:
        measured_rate = clock.rate_hz()
        if rate_hz is not None and abs(rate_hz / measured_rate - 1) > TIME_JITTER_TOLERANCE:
            raise InputError(
                f"{stream.source}: the rate given, {rate_hz:.9g} Hz, disagrees with the time "
                f"column {time_column!r}, whose steps give {measured_rate:.9g} Hz (relative "
                f"difference {abs(rate_hz / measured_rate - 1):.3g}); give one of them "
                "(rate_hz or time_column)",
                parameter="rate_hz",
            )
        rate_hz = measured_rate
    found = measured.finish()
    if unwrap is not None and (ambiguous := unwrap.warning(stream.source)) is not None:
        found.append(ambiguous)
    for warning in found:
        warnings.warn(warning, stacklevel=2)
    return NoiseSeries(
        source=stream.source,
        frequency_hz=frequency_hz,
        rate_hz=float(rate_hz),
        meter_std_hz=math.sqrt(variance_sum / variance_count) if variance_count else None,
        fsr_hz=fsr_hz,
        scale_rel_std=_scale_rel_std(calibration),
        unwrapped=modulo,
        rows=frequency_hz.size,
        excluded=excluded,
        flagged=flagged,
        excluded_counts={bit.name: counts[bit.name] for bit in EXCLUDED_FLAGS if counts[bit.name]},
        flag_counts={name: count for name, count in counts.items() if count},
        ambiguous_steps=0 if unwrap is None else unwrap.ambiguous,
        time_column=time_column,
        invalid_examples=list(stream.invalid_examples),
        warnings=tuple(found),
    )

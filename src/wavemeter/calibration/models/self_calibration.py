"""Self-calibration: a sweep with no frequency axis, a reference cell, and the band.

:func:`sweep_phase_reference_free` gives the meter's unwrapped phase along a sweep from the
powers alone: a cone fitted to the whole sweep unwraps it roughly; the cone is then fitted
again on windows of one fringe (half overlapping), where the map is nearly constant even
when it changes across a wide band; each window's phase takes the rough one's direction
and is joined to the previous window's where they overlap (the first to the rough phase's
mean), and each sample is read in the window centred nearest to it. :func:`self_calibrate`
then finds, fits and identifies the cell's lines in that phase by their spacings within the
band and fits the axis ``f = g(phi)``: the FSR, the offset and the dispersion come from the
line positions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...exceptions import InputError
from ...reference import ReferenceLines, SweepAxis, axis_from_phase
from ...validation import check_dark, check_positive, check_powers
from .cone_fit import ConeFit, cone_phase_rad, fit_cone

__all__ = ["SelfCalibration", "self_calibrate", "sweep_phase_reference_free"]

#: fewest readings in a window of one fringe for its own cone fit
MIN_WINDOW_READINGS = 64


def _wrap(phase):
    return np.angle(np.exp(1j * np.asarray(phase)))


def sweep_phase_reference_free(powers, *, offsets: str = "none", window_rad: float = 2 * np.pi):
    """The meter's unwrapped phase along a sweep, from the powers alone (module docstring).

    Parameters
    ----------
    powers : array_like, shape (N, n)
        The sweep's readings in sweep order (dark readings subtracted), dense enough that the
        phase moves by well under pi from one reading to the next.
    offsets : {"none", "fit"}
        Detector offsets for the cone fits (:func:`~.cone_fit.fit_cone`).
    window_rad : float
        Width of the windows (rad of phase); one fringe by default.

    Returns
    -------
    phase_rad : ndarray, shape (N,)
        Unwrapped phase (rad); its origin and direction are arbitrary.
    cone : ConeFit
        The cone fitted to the whole sweep.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.calibration import sweep_phase_reference_free
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(2000, span_fsr=5)  # five fringes, no frequency axis used
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> phase, _ = sweep_phase_reference_free(powers)

    The unwrapped phase counts the fringes: 2 pi per FSR swept (up to its sign):

    >>> print(f"{abs(phase[-1] - phase[0]) / (2 * np.pi):.2f} fringes")
    5.00 fringes
    """
    readings = check_powers(powers, min_samples=MIN_WINDOW_READINGS)
    check_positive("window_rad", window_rad)
    cone = fit_cone(readings, offsets=offsets)
    rough = np.unwrap(cone_phase_rad(cone, readings))
    span = rough.max() - rough.min()
    if span < window_rad:
        return rough, cone
    centers = np.arange(rough.min() + window_rad / 2, rough.max(), window_rad / 2)
    nearest = np.argmin(np.abs(rough[:, None] - centers[None, :]), axis=1)
    phase = rough.copy()
    previous = None  # the last window's samples and its phase of them
    for k, center in enumerate(centers):
        inside = np.abs(rough - center) <= window_rad / 2
        if inside.sum() < MIN_WINDOW_READINGS:
            previous = None
            continue
        local = np.unwrap(
            cone_phase_rad(fit_cone(readings[inside], offsets=offsets), readings[inside])
        )
        sign = 1.0 if np.polyfit(rough[inside], local, 1)[0] > 0 else -1.0
        difference = _wrap(sign * local - rough[inside])
        # near the rough phase first, then onto the previous window where they overlap
        aligned = rough[inside] + _wrap(difference - np.angle(np.mean(np.exp(1j * difference))))
        if previous is not None:
            shared = inside & previous[0]
            if shared.sum() >= MIN_WINDOW_READINGS // 2:
                mine = np.flatnonzero(inside)
                lookup = np.searchsorted(mine, np.flatnonzero(shared))
                aligned += np.mean(previous[1][shared] - aligned[lookup])
        full = np.full(rough.size, np.nan)
        full[inside] = aligned
        previous = (inside, full)
        chosen = inside & (nearest == k)
        phase[chosen] = full[chosen]
    return phase, cone


@dataclass(frozen=True)
class SelfCalibration:
    """What a sweep without a frequency axis gives with a reference cell.

    Attributes
    ----------
    frequency_hz : ndarray, shape (N,)
        The sweep's absolute frequency axis from the lines (Hz): fit a calibration on it.
    phase_rad : ndarray, shape (N,)
        The meter's unwrapped (smoothed) phase of every sample (rad, the axis's argument).
    axis : SweepAxis
        Lines, identification, correction ``g`` and its uncertainty budget.
    cone : ConeFit
        The cone learned from the sweep's powers (its ``map_w()``).
    fsr_hz : float
        The FSR at ``center_hz`` (Hz), ``2 pi |dg/dphi|``.
    center_hz : float
        ``g`` at the middle of the lines' phases (Hz): the offset.
    delay_s, dispersion_s2 : float
        Taylor coefficients of the phase in angular frequency at ``center_hz``:
        ``d phi / d omega`` (s) and ``d^2 phi / d omega^2`` (s^2), with the phase's sign
        taken to grow with frequency.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.calibration import self_calibrate
    >>> from wavemeter.simulation import ReferenceCell, laser_sweep
    >>> cell = ReferenceCell.simulated(rng=1)  # a simulated HCN-like cell of 54 lines
    >>> band_hz = (cell.lines.center_hz[20] - 40e9, cell.lines.center_hz[27] + 40e9)  # 8 lines
    >>> sweep = laser_sweep(band_hz, 4000, "dfb", rng=1)  # a current-tuned laser: a poor axis
    >>> device = wm.Interferometer.table1(ports=3, seed=1)
    >>> powers = device.powers(sweep.true_hz, power_w=1e-3, noise_w=5e-7, rng=2)
    >>> transmission = cell.transmission(sweep.true_hz, rng=3)  # the cell channel
    >>> found = self_calibrate(
    ...     powers, transmission, cell.lines, band_hz, fsr_hz=50e9,
    ...     pressure_pa=cell.nominal_pressure_pa, pressure_std_pa=cell.pressure_std_pa,
    ... )
    >>> found.frequency_hz.shape, found.phase_rad.shape
    ((4000,), (4000,))
    >>> print(f"FSR {found.fsr_hz / 1e9:.2f} GHz, true {device.true_fsr_hz / 1e9:.2f} GHz")
    FSR 49.59 GHz, true 49.58 GHz
    >>> cal = wm.WidebandCalibrator(fsr_hz=50e9).fit(powers, found.frequency_hz)  # calibrate
    >>> cal.method
    'wideband'
    """

    frequency_hz: np.ndarray
    phase_rad: np.ndarray
    axis: SweepAxis
    cone: ConeFit
    fsr_hz: float
    center_hz: float
    delay_s: float
    dispersion_s2: float


def self_calibrate(
    powers,
    transmission,
    lines: ReferenceLines,
    band_hz,
    *,
    fsr_hz: float = 50e9,
    fsr_tolerance: float = 0.2,
    dark_w=None,
    offsets: str = "none",
    pressure_pa: float | None = None,
    pressure_std_pa: float = 0.0,
    order: int | None = None,
    smoothing_samples: int | None = None,
) -> SelfCalibration:
    """Calibrate a sweep's frequency axis from the powers, a reference cell and the band.

    Parameters
    ----------
    powers : array_like, shape (N, n)
        The sweep's port readings, in sweep order.
    transmission : array_like, shape (N,)
        The cell channel, one reading per sample.
    lines : ReferenceLines
        The cell's table.
    band_hz : (float, float)
        The band the sweep covers (Hz); the lines are identified among the table's lines in
        it, by their spacings.
    fsr_hz, fsr_tolerance : float
        Design FSR (Hz) and its relative tolerance: bounds the phase-to-frequency scale.
    dark_w : None or array_like, shape (n,)
        Dark readings (W), subtracted.
    offsets, pressure_pa, pressure_std_pa, order, smoothing_samples :
        As for :func:`sweep_phase_reference_free` and
        :func:`~wavemeter.reference.axis_from_phase`.

    Returns
    -------
    SelfCalibration

    Raises
    ------
    InputError
        For bad readings, or lines that cannot be identified uniquely in the band (the
        reason).

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.calibration import self_calibrate
    >>> from wavemeter.simulation import ReferenceCell, laser_sweep
    >>> cell = ReferenceCell.simulated(rng=1)  # a simulated HCN-like cell of 54 lines
    >>> band_hz = (cell.lines.center_hz[20] - 40e9, cell.lines.center_hz[27] + 40e9)  # 8 lines
    >>> sweep = laser_sweep(band_hz, 4000, "dfb", rng=1)  # a current-tuned laser: a poor axis
    >>> device = wm.Interferometer.table1(ports=3, seed=1)
    >>> powers = device.powers(sweep.true_hz, power_w=1e-3, noise_w=5e-7, rng=2)
    >>> transmission = cell.transmission(sweep.true_hz, rng=3)  # the cell channel
    >>> found = self_calibrate(
    ...     powers, transmission, cell.lines, band_hz, fsr_hz=50e9,
    ...     pressure_pa=cell.nominal_pressure_pa, pressure_std_pa=cell.pressure_std_pa,
    ... )

    The laser's own axis is off by tens of GHz; the axis found from the meter's phase and
    the cell's lines is right to a few MHz, without any frequency given:

    >>> axis_error_hz = sweep.recorded_hz - sweep.true_hz
    >>> print(f"recorded axis: up to {np.abs(axis_error_hz).max() / 1e9:.0f} GHz off")
    recorded axis: up to 56 GHz off
    >>> error_hz = found.frequency_hz - sweep.true_hz
    >>> print(f"found axis: {np.sqrt(np.mean(error_hz**2)) / 1e6:.0f} MHz RMS")
    found axis: 6 MHz RMS
    >>> found.axis.identification.method  # lines named by their spacings
    'pattern'
    """
    check_positive("fsr_hz", fsr_hz)
    check_positive("fsr_tolerance", fsr_tolerance, upper=1.0)
    readings = check_powers(powers)
    dark = check_dark(dark_w, readings.shape[1])
    if dark is not None:
        readings = readings - dark
    if band_hz is None:
        raise InputError(
            "a sweep without a frequency axis needs band_hz, the band it covers (Hz)",
            parameter="band_hz",
        )
    phase, cone = sweep_phase_reference_free(readings, offsets=offsets)
    scale = fsr_hz / (2 * np.pi)
    axis = axis_from_phase(
        phase,
        transmission,
        lines,
        band_hz=band_hz,
        scale_range=(scale * (1 - fsr_tolerance), scale * (1 + fsr_tolerance)),
        pressure_pa=pressure_pa,
        pressure_std_pa=pressure_std_pa,
        order=order,
        smoothing_samples=smoothing_samples,
    )
    correction = axis.correction
    middle = correction.phase_center_rad
    slope = float(correction.slope_hz_per_rad(middle))
    derivative = np.polynomial.legendre.legder(correction.coefficients_hz, 2)
    curvature = float(np.polynomial.legendre.legval(0.0, derivative)) / correction.phase_half_rad**2
    sign = np.sign(slope)
    # phi(omega) is the inverse of g: d phi / d omega = 1 / (2 pi g'), and
    # d^2 phi / d omega^2 = -g'' / ((2 pi)^2 g'^3), with phi's sign made to grow with f
    return SelfCalibration(
        frequency_hz=axis.frequency_hz,
        phase_rad=axis.phase_rad,
        axis=axis,
        cone=cone,
        fsr_hz=axis.fsr_hz,
        center_hz=float(correction.frequency_hz(middle)),
        delay_s=float(sign / (2 * np.pi * slope)),
        dispersion_s2=float(-sign * curvature / ((2 * np.pi) ** 2 * slope**3)),
    )

"""Naming the cause of a misfit: the causes, their warnings and their remedies.

From the tests on the residual (:mod:`.residual_tests`) the residual gets at most one of
``power_drift``, ``phase_drift``, ``dispersion`` and ``other_misfit`` (the candidate with
the largest excess energy, ties named phase, power, other; on a sweep of several FSRs a
structure a polynomial in frequency explains is ``dispersion`` when it is a phase or the
ports change each in its own way, :mod:`.band_tests`); a rounded frequency axis the
residual follows is ``quantised_axis`` (:mod:`.axis_tests`); the checks of the map and the
sweep add ``detector_offset``, ``partial_span``, ``unequal_noise`` and ``ill_conditioned``.
Each is a :class:`~wavemeter.exceptions.CalibrationWarning` whose ``cause`` is one of
:data:`CAUSES`, with what was seen (its numbers) and what to do (:data:`REMEDIES`). The
rules are in ``docs/theory/diagnostics.rst`` ("Naming the cause", "Checks of the map and
the sweep").
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from ...exceptions import CalibrationWarning
from ...stats.nested_tests import TEST_P_VALUE, ResidualTest
from ...units import frequency_text
from .axis_tests import AxisQuantisation, AxisTest
from .band_tests import BAND_DEGREES, BandTests
from .residual_tests import DISPERSION_MIN_SPAN_FSR, Structure, rms

__all__ = [
    "CAUSES",
    "REMEDIES",
    "WIDE_SWEEP_REMEDY",
    "WIDE_BAND_METHODS",
    "EXPLAINED_FRACTION",
    "TIE_FRACTION",
    "TIE_Z",
    "MIN_OFFSET_Z",
    "SPAN_TOLERANCE",
    "UNEQUAL_NOISE_RATIO",
    "MAX_PINV_VARIANCE_RATIO",
    "SLOPE_SHARE",
    "misfit_warning",
    "quantised_axis_warning",
    "offset_warning",
    "unequal_noise",
    "partial_span_warning",
    "ill_conditioned_warning",
]

#: the causes a :class:`~wavemeter.exceptions.CalibrationWarning` of this module names
CAUSES = (
    "power_drift",
    "detector_offset",
    "phase_drift",
    "dispersion",
    "partial_span",
    "unequal_noise",
    "ill_conditioned",
    "quantised_axis",
    "other_misfit",
)
#: share of the smooth structure a cause must explain to be named
EXPLAINED_FRACTION = 0.5
#: causes explaining within this fraction, and TIE_Z noise standard deviations, of the
#: best are a tie (named phase, power, other)
TIE_FRACTION = 0.02
TIE_Z = 2.0
#: significance (standard errors) of a fitted offset that warns
MIN_OFFSET_Z = 5.0
#: a sweep shorter than 1 - SPAN_TOLERANCE FSR is partial
SPAN_TOLERANCE = 0.05
#: port noises differing by more than this factor (and significantly) are unequal
UNEQUAL_NOISE_RATIO = 1.3
#: pseudo-inverse phase variance over the Cramer-Rao bound's that is ill-conditioned
MAX_PINV_VARIANCE_RATIO = 1.2**2
#: share of a wide sweep's structure polynomial in frequency that no common change of the
#: source power or the fringe phase explains, from which the device's wavelength dependence
#: is named (a drift leaves less: only its second-order terms)
SLOPE_SHARE = 0.05

#: the calibrations of a band of several FSRs, by their ``method``: what a remedy of a
#: misfit on such a band suggests (after "calibrate"), less the method already in use
WIDE_BAND_METHODS = {
    "wideband": "the band with WidebandCalibrator (a map smooth in frequency)",
    "calibration_set": "per FSR (CalibrationSet)",
}
#: why a misfit no cause explains on a sweep of several FSRs may be the band's
WIDE_SWEEP_REASON = (
    "over a sweep of several FSRs the couplers and photodiodes change with the wavelength"
)
#: the first remedy of such a misfit
WIDE_SWEEP_REMEDY = f"{WIDE_SWEEP_REASON}: calibrate " + ", or ".join(WIDE_BAND_METHODS.values())

REMEDIES = {
    "power_drift": (
        "record the source power with a power monitor during the sweep (power_monitor_w), "
        "or stabilise the source"
    ),
    "detector_offset": (
        "pass dark readings taken with the source off (dark_w), so that the offsets are "
        "subtracted rather than fitted"
    ),
    "phase_drift": (
        "stabilise the chip temperature, or log it with every reading for a thermal "
        "calibration; a linear temperature ramp over a one-way sweep cannot be seen here "
        "(it is absorbed into the FSR)"
    ),
    "dispersion": (
        "calibrate the band with WidebandCalibrator (a phase polynomial and a map smooth in "
        "frequency, orders chosen by cross-validation), or per FSR (CalibrationSet)"
    ),
    "partial_span": "calibrate over at least one FSR",
    "quantised_axis": (
        "record the frequency (or wavelength) at full precision: export it from the "
        "instrument or its software with all its digits, not through a spreadsheet or a "
        "format that rounds it, and calibrate again"
    ),
    "unequal_noise": 'use the maximum-likelihood retrieval (retrieval="ml"), which weights '
    "the ports by their noise",
    "ill_conditioned": 'use the maximum-likelihood retrieval (retrieval="ml"), which reaches '
    "the Cramer-Rao bound for any map",
    "other_misfit": (
        "inspect the residual in the calibration diagnostics; check the detectors for "
        "nonlinearity or saturation and the setup for stray light, back-reflections or a "
        "wandering background"
    ),
}


def _excess(test: ResidualTest | None) -> float:
    """Excess energy of a failed test, 0 for one that passed or was not made."""
    return test.excess if test is not None and test.failed else 0.0


def _cause(structure: Structure, band: BandTests | None, axis_phase: bool = False) -> str:
    """The alternative that explains the residual best (``docs/theory/diagnostics.rst``);
    ``axis_phase``: the phase smooth along the rows is a corrected axis's, not tested."""
    if not structure.smooth_failed:
        scatter = structure.scatter
        return "power_drift" if scatter.power_excess >= scatter.phase_excess else "phase_drift"
    phase, dispersion = _excess(structure.phase), _excess(structure.dispersion)
    explained = {  # in the order ties are named
        "phase_drift": max(phase, dispersion),
        "power_drift": _excess(structure.power),
        "other_misfit": structure.harmonics.excess,
    }
    best = max(explained.values())
    cause = (
        "other_misfit"
        if best <= 0.0 or best < EXPLAINED_FRACTION * structure.smooth.excess
        else next(name for name, value in explained.items() if _ties(value, best))
    )
    if axis_phase and cause == "power_drift" and not _ties(best, structure.smooth.excess):
        # the phase's share of any structure went into the axis: what is left must be the
        # power's alone (a port's own background leaves some across the image too)
        return "other_misfit"
    # harmonics of the fringe (a detector's nonlinearity) are no change with frequency,
    # though a polynomial times the fringe mimics them over a few FSRs
    harmonic = cause == "other_misfit" and _ties(structure.harmonics.excess, best)
    if (
        not harmonic
        and _in_frequency(structure, band)
        and (cause == "phase_drift" or _ports_own(band))
    ):
        return "dispersion"
    if cause == "phase_drift" and dispersion > 0.0 and _ties(dispersion, phase):
        return "dispersion"
    return cause


def _in_frequency(structure: Structure, band: BandTests | None) -> bool:
    """Whether a map polynomial in frequency explains the smooth structure of a wide sweep:
    what is smooth along the rows beyond it passes, or ties with nothing."""
    if band is None or not band.band.failed:
        return False
    if not band.remainder.failed:
        return True
    smooth = structure.smooth.excess
    return _ties(smooth - band.remainder.excess, smooth)


def _ports_own(band: BandTests) -> bool:
    """Whether the ports change with frequency each in its own way: beyond a common change
    of power and phase (``SLOPE_SHARE`` of the structure polynomial in frequency)."""
    return band.slope.failed and band.slope.excess >= SLOPE_SHARE * band.band.excess


def _ties(value: float, best: float) -> bool:
    """Whether ``value`` explains as much as ``best`` within the tolerance of a tie."""
    return best - value <= TIE_FRACTION * best + TIE_Z * np.sqrt(max(best, 0.0))


def _p_text(p_value: float) -> str:
    """``p-value 3.1e-09``, or ``p-value < 1e-300`` where it underflows."""
    return "p-value < 1e-300" if p_value < 1e-300 else f"p-value {p_value:.2g}"


def _port_list(names, mask) -> str:
    return ", ".join(name for name, flag in zip(names, mask, strict=True) if flag)


def _warning(cause: str, seen: str, remedy: str | None = None) -> CalibrationWarning:
    remedy = REMEDIES[cause] if remedy is None else remedy
    return CalibrationWarning(f"{seen}; {remedy}", cause=cause, remedy=remedy)


def _power_clause(error: np.ndarray) -> str:
    return (
        f"a relative source-power error of {100 * rms(error):.3g} % RMS "
        f"({100 * np.abs(error).max():.3g} % peak)"
    )


def _phase_clause(error: np.ndarray, delay_s: float) -> str:
    per_rad_mhz = 1e-6 / (2.0 * np.pi * delay_s)
    return (
        f"a phase error of {rms(error):.3g} rad RMS ({rms(error) * per_rad_mhz:.3g} MHz, "
        f"{np.abs(error).max():.3g} rad peak)"
    )


def _wide_sweep_remedy(method: str | None) -> str | None:
    """``WIDE_SWEEP_REMEDY`` without the calibration ``method`` in use; None when it offers
    nothing else."""
    others = [text for name, text in WIDE_BAND_METHODS.items() if name != method]
    return f"{WIDE_SWEEP_REASON}: calibrate " + ", or ".join(others) if others else None


def misfit_warning(
    structure,
    band,
    names,
    ratio,
    lag1,
    harmonic_power,
    span,
    delay,
    model_free,
    method=None,
    axis_phase=False,
):
    """The one warning that names the misfit, or None when every residual test passes
    (``band`` the tests of a wide sweep against a polynomial in frequency, or None;
    ``method`` the calibration's, which no remedy suggests; ``axis_phase``: the phase
    smooth along the rows is a corrected axis's, not tested)."""
    if not structure.failed:
        return None
    cause = _cause(structure, band, axis_phase)
    residual = f"lag-1 autocorrelation of the residual up to {lag1.max():.2f}"
    if model_free:
        high = ratio >= min(ratio.max(), 1.0 + 0.5 * (ratio.max() - 1.0))
        residual = (
            f"residual up to {ratio.max():.3g}x the model-free noise "
            f"({_port_list(names, high)}), {residual}"
        )
    power, phase, scatter = structure.power, structure.phase, structure.scatter
    # a drift of power and one of phase that leave the same residual (a sweep of ~1 FSR)
    tie = _ties(power.excess, phase.excess)
    if not structure.smooth_failed:
        direction, error = (
            ("power", f"{100 * scatter.power_rms:.3g} % RMS of relative source-power noise")
            if cause == "power_drift"
            else ("phase", f"{scatter.phase_rms_rad:.3g} rad RMS of phase noise")
        )
        seen = (
            f"the readings scatter along the fringe's {direction} direction more than across "
            f"it: {error} from reading to reading, beyond the detector noise (p-value "
            f"{min(scatter.power_p, scatter.phase_p):.2g}; {residual})"
        )
    elif cause == "power_drift":
        seen = (
            f"the source power drifts along the sweep: {_power_clause(structure.power_error)} "
            f"remains in the residual after the fit ({residual}); without a power monitor "
            "part of a drift is absorbed into the map and the FSR"
        )
        if _in_frequency(structure, band) and band.single_map and method != "wideband":
            seen += (
                f"; over this {span:.3g} FSR sweep a polynomial in frequency explains it, as "
                "detectors whose responsivity changes with the wavelength alike would give: "
                "a monitor does not remove that, a wide-band calibration (WidebandCalibrator) "
                "does"
            )
    elif cause == "dispersion" and _in_frequency(structure, band):
        seen = _band_clause(structure, band, span, delay) + f" ({residual})"
    elif cause == "phase_drift":
        seen = (
            f"the fringe phase drifts along the sweep: "
            f"{_phase_clause(structure.phase_error_rad, delay)} that is not a polynomial "
            f"in frequency remains in the residual ({residual})"
        )
        if tie and power.failed:
            seen += (
                f"; on this sweep {_power_clause(structure.power_error)} would leave the "
                "same residual: if the source power was not monitored, suspect it too"
            )
    elif cause == "dispersion":
        seen = (
            f"the fringe phase is not linear in frequency over the {span:.3g} FSR sweep: "
            f"{_phase_clause(structure.dispersion_rad, delay)} even in f - f0 remains in "
            f"the residual, as group-delay dispersion gives ({residual}); the FSR changes "
            "across the sweep"
        )
    else:
        seen = (
            f"the residual departs from white noise in a way no listed cause explains "
            f"({residual}; harmonics 2-3 of the fringe phase up to "
            f"{harmonic_power.max():.3g}x their noise level)"
        )
        wide = _wide_sweep_remedy(method)
        if span > DISPERSION_MIN_SPAN_FSR and wide is not None:
            # over many FSRs the couplers and photodiodes change with the wavelength
            return _warning(cause, seen, f"{wide}; else {REMEDIES[cause]}")
    return _warning(cause, seen)


def _band_clause(structure: Structure, band: BandTests, span: float, delay: float) -> str:
    """What a wide sweep's structure polynomial in frequency shows: the ports' own changes,
    the phase's curvature, or both."""
    parts = []
    if _ports_own(band):
        share = band.slope.excess / band.band.excess
        parts.append(
            f"the ports' fringes change with frequency each in its own way, as the couplers' "
            f"and detectors' wavelength dependence makes them and no drift in time does: "
            f"{100 * share:.3g} % of the structure is no common change of the source power or "
            f"the fringe phase ({_p_text(band.slope.p_value)})"
        )
    dispersion = structure.dispersion
    if dispersion is not None and dispersion.failed:
        parts.append(
            f"{_phase_clause(structure.dispersion_rad, delay)} even in f - f0 remains, as "
            "group-delay dispersion gives"
        )
    elif not parts:
        parts.append(
            f"{_phase_clause(structure.phase_error_rad, delay)} remains, the FSR changing "
            "across the sweep (on a one-way sweep a slow drift of the chip temperature "
            "would leave the same)"
        )
    return (
        f"the device changes with frequency over the {span:.3g} FSR sweep: a polynomial of "
        f"degree {BAND_DEGREES} in frequency explains the residual's smooth structure "
        f"({_p_text(band.band.p_value)}); " + "; ".join(parts)
    )


def quantised_axis_warning(
    axis: AxisQuantisation, test: AxisTest, samples: int, delay_s: float
) -> CalibrationWarning:
    """``quantised_axis``: the recorded axis is rounded and the residual follows it."""
    grid = ""
    if axis.grid is not None:
        unit, step = axis.grid
        grid = (
            f", every value on a grid of {frequency_text(step, 3)} in frequency"
            if unit == "frequency"
            else f", every value on a grid of {step * 1e9:g} nm in wavelength"
        )
    error = test.phase_error_rad
    per_rad_mhz = 1e-6 / (2.0 * np.pi * delay_s)
    departure = rms(axis.departure_hz)
    return _warning(
        "quantised_axis",
        f"the frequency axis is rounded: {axis.distinct} distinct values in {samples} "
        f"readings (median step {frequency_text(axis.step_hz, 3)}{grid}), and the residual "
        "phase follows each reading's departure from a smooth sweep (coefficient "
        f"{test.coefficient:.2f}, 1 when it follows the rounding one for one; "
        f"{_p_text(test.test.p_value)}): a sawtooth of {rms(error):.3g} rad RMS "
        f"({rms(error) * per_rad_mhz:.3g} MHz) within each step, as rounding to steps of "
        f"about {frequency_text(np.sqrt(12.0) * departure, 3)} gives; the calibration is "
        "learned at frequencies up to half a step from the true ones",
    )


def offset_warning(offsets, offset_std, readings, names):
    """``detector_offset`` when a fitted offset exceeds ``MIN_OFFSET_Z`` standard errors."""
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.abs(offsets) / offset_std
    z = np.where(offset_std > 0, z, np.where(offsets != 0, np.inf, 0.0))
    significant = z > MIN_OFFSET_Z
    if not significant.any():
        return None
    mean = np.abs(readings.mean(axis=0))
    parts = [
        f"{names[j]} {offsets[j]:+.3g} W ({100 * offsets[j] / mean[j]:+.3g} % of its mean "
        f"reading, {z[j]:.3g} standard errors)"
        for j in np.flatnonzero(significant)
    ]
    return _warning(
        "detector_offset",
        f"the readings carry offsets independent of the source power: {'; '.join(parts)}; "
        "they were fitted from the power variation the monitor shows",
    )


def unequal_noise(noise, dof, names):
    """``unequal_noise`` warning (or None) and the test's p-value."""
    ports = noise.size
    factor = float(noise.max() / noise.min())
    # two noise variances on nu degrees of freedom each: their ratio is F(nu, nu)
    p_value = float(min(1.0, ports * (ports - 1) * stats.f.sf(factor**2, dof, dof)))
    if factor <= UNEQUAL_NOISE_RATIO or p_value >= TEST_P_VALUE:
        return None, p_value
    levels = ", ".join(f"{name} {level:.3g} W" for name, level in zip(names, noise, strict=True))
    return (
        _warning(
            "unequal_noise",
            f"the ports' noise differs by a factor {factor:.3g} ({levels}; p-value "
            f"{p_value:.2g}): the pseudo-inverse retrieval weights them equally",
        ),
        p_value,
    )


def partial_span_warning(span: float, delay: float) -> CalibrationWarning | None:
    """``partial_span`` when the sweep covers less than ``1 - SPAN_TOLERANCE`` of the fitted
    FSR (``span`` in FSRs, ``delay`` the fitted delay in s), else None."""
    if span < 1.0 - SPAN_TOLERANCE:
        return _warning(
            "partial_span",
            f"the sweep covers {span:.3g} of the fitted FSR ({1e-9 / delay:.6g} GHz): the "
            "map is learned from part of the fringe and readings outside the span are "
            "extrapolated",
        )
    return None


def ill_conditioned_warning(variance_ratio: float, condition: float) -> CalibrationWarning | None:
    """``ill_conditioned`` when the pseudo-inverse's phase variance exceeds the Cramer-Rao
    bound's by more than ``MAX_PINV_VARIANCE_RATIO`` (``condition`` the map's condition
    number, for the message), else None."""
    if variance_ratio > MAX_PINV_VARIANCE_RATIO:
        return _warning(
            "ill_conditioned",
            f"the pseudo-inverse retrieval's phase variance is {variance_ratio:.3g}x the "
            f"Cramer-Rao bound's over the sweep (allowed {MAX_PINV_VARIANCE_RATIO:.3g}x; "
            f"map condition number {condition:.3g})",
        )
    return None

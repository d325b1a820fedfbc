"""What limits or qualifies a frequency-noise result, each a warning with a remedy.

:func:`findings` reads a :class:`~wavemeter.analysis.noise_result.FrequencyNoise` with the
power-law fit and the beta linewidth it came from, and gives one
:class:`~wavemeter.exceptions.CalibrationWarning` per finding (excluded readings, an unknown
floor, white FM below it, a misfit of the power law, the beta linewidth's limits and
extrapolation), each with its numbers and what to do; ``WARNING_CAUSES`` lists the causes.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import CalibrationWarning
from .noise_fit import MISFIT_P_VALUE, UPPER_LIMIT_SIGMAS, BetaLinewidth, PowerLawFit
from .noise_result import FrequencyNoise

__all__ = ["WARNING_CAUSES", "findings"]

#: cause of each warning -> what it means
WARNING_CAUSES = {
    "excluded_readings": "NaN readings were dropped at the ends or bridged inside",
    "floor_unknown": "the meter's noise is unknown: its floor is not subtracted",
    "below_floor": "the laser's white FM is not significantly above the meter's floor",
    "beta_lower_limit": "the PSD is above the beta line up to the highest frequency",
    "beta_upper_limit": "the PSD is not significantly above the beta line: an upper limit",
    "beta_below_line": "the PSD is nowhere above the beta line: the beta linewidth is 0",
    "beta_extrapolated": "the beta integral starts below the lowest PSD band",
    "noise_model_misfit": "the PSD departs from h0 + h_-1/f + h_-2/f^2",
}


def _warning(cause: str, seen: str, remedy: str) -> CalibrationWarning:
    return CalibrationWarning(f"{seen}; {remedy}", cause=cause, remedy=remedy)


def findings(
    result: FrequencyNoise,
    dropped: int,
    bridged: int,
    fit: PowerLawFit,
    beta: BetaLinewidth,
    low_hz: float,
) -> list[CalibrationWarning]:
    """The warnings a result calls for, each with its numbers and a remedy."""
    found = []
    series_size = round(result.duration_s * result.rate_hz)
    if dropped or bridged:
        found.append(
            _warning(
                "excluded_readings",
                f"{dropped + bridged} of {result.n_readings + result.n_excluded} readings are "
                f"NaN (excluded): {dropped} at the ends dropped, {bridged} inside bridged by "
                f"linear interpolation ({bridged / series_size:.2%} of the series analysed); "
                "a bridged reading carries no noise of its own, so the PSD's white level is "
                "low by up to about that fraction",
                "find why readings were excluded (flags, glitches, dropouts) and re-measure, "
                "or analyse an unbroken stretch",
            )
        )
    h0, h0_std = result.white_fm_hz2_per_hz, result.white_fm_std_hz2_per_hz
    floor = result.meter_floor_hz2_per_hz
    if floor is None:
        found.append(
            _warning(
                "floor_unknown",
                "the meter's own noise is unknown (no meter_std_hz): its white floor is not "
                "subtracted, so the white FM level and the Lorentzian linewidth, "
                f"< {result.lorentzian_linewidth_hz:.3g} Hz, are upper limits",
                "give each reading's frequency_std_hz (or their RMS) as meter_std_hz",
            )
        )
    elif result.linewidth_is_upper_limit:
        found.append(
            _warning(
                "below_floor",
                f"the laser's white FM level {h0:.3g} +- {h0_std:.3g} Hz^2/Hz is not above "
                f"both the meter's floor {floor:.3g} Hz^2/Hz and {UPPER_LIMIT_SIGMAS:g} "
                "standard deviations: the Lorentzian linewidth is an upper limit, "
                f"< {result.lorentzian_linewidth_hz:.3g} Hz",
                "lower the meter's noise (more optical power, a longer delay) or average "
                "more readings per sample, or measure with a quieter meter",
            )
        )
    if fit.misfit:
        found.append(
            _warning(
                "noise_model_misfit",
                f"the PSD departs from h0 + h_-1/f + h_-2/f^2 (chi-square {fit.chi2:.3g} for "
                f"{fit.dof} degrees of freedom, p < {MISFIT_P_VALUE:g}): the standard "
                f"deviations of the fit are scaled up by {np.sqrt(fit.chi2 / fit.dof):.3g}, "
                "and the levels may still be biased",
                "look at the PSD for peaks or bumps (servo, vibration, mains) or white phase "
                "noise, and analyse a record or band where the power law holds",
            )
        )
    start_hz = 1.0 / result.beta_observation_time_s
    if beta.extrapolated:
        found.append(
            _warning(
                "beta_extrapolated",
                f"the beta integral starts at 1 / T_obs = {start_hz:.3g} Hz, below the lowest "
                f"PSD band ({low_hz:.3g} Hz): the fitted power law stands in there, and its "
                "uncertainty dominates the beta linewidth's",
                f"give an observation time of at most {1 / low_hz:.3g} s (the default), or "
                "record longer",
            )
        )
    if beta.upper_limit:
        found.append(
            _warning(
                "beta_upper_limit",
                "the corrected PSD is not significantly above the beta separation line from "
                f"1 / T_obs = {start_hz:.3g} Hz up (the bands' noise alone gives an area as "
                f"large with probability {beta.p_value:.2g}): only excursions above the line "
                "count, so the area is biased up, and the beta linewidth is an upper limit, "
                f"< {result.beta_linewidth_hz:.3g} Hz",
                "record longer (more averages in the low bands, a longer T_obs), lower the "
                "meter's floor, or use the Lorentzian linewidth",
            )
        )
    elif beta.area_hz2 <= 0:
        found.append(
            _warning(
                "beta_below_line",
                "the laser's corrected PSD is below the beta separation line everywhere from "
                f"1 / T_obs = {start_hz:.3g} Hz up: its frequency noise is too fast or too weak "
                "to broaden the line within T_obs, and the beta linewidth is 0 within its "
                f"uncertainty ({result.beta_linewidth_std_hz:.3g} Hz)",
                "record longer (a longer T_obs reaches slower noise), or use the Lorentzian "
                "linewidth",
            )
        )
    elif beta.lower_limit:
        highest = result.psd_freqs_hz[np.isfinite(result.psd_corrected_hz2_per_hz)][-1]
        found.append(
            _warning(
                "beta_lower_limit",
                "the corrected PSD is still above the beta separation line at the highest "
                f"frequency analysed ({highest:.3g} Hz): the beta linewidth, > "
                f"{beta.fwhm_hz:.3g} Hz, is a lower limit",
                "sample faster so that the PSD reaches the line, or use a larger-FSR meter "
                "when the delay correction limit cuts the band",
            )
        )
    return found

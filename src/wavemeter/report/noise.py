"""The HTML page of a frequency-noise analysis (``wavemeter noise -o noise.html``).

Self-contained like the calibration report (figures embedded as base64 PNG, every text
escaped, no scripts): the inputs and how the series was measured (rate, readings excluded
and why, unwrapping), a summary table where each number carries its uncertainty and unit
(an upper limit shown ``< x``, a lower limit ``> x``), the warnings, the figures
(:mod:`.noise_figures`: the series, the PSD with the meter floor and the beta line, the
Allan deviations), a table of the deviations with their confidence intervals, and the
physics the numbers follow. Written atomically: a failure leaves no page.
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from ..atomic import STDOUT, atomic_path, check_output
from ..exceptions import InputError
from ..units import SPEED_OF_LIGHT_M_S, frequency_text
from .formatting import scientific, scientific_with_error, significant, with_error
from .html import DEFAULT_DPI, png_bytes
from .noise_figures import frequency_scale, noise_figures
from .page import PAGE_STYLE, figures_html, html_table

__all__ = [
    "write_noise_report",
    "render_noise_page",
    "summary_rows",
    "NOISE_FIGURE_CAPTIONS",
    "NOISE_REFERENCES",
]

NOISE_FIGURE_CAPTIONS = {
    "frequency": "Frequency of the readings against time (a long record as block means with "
    "each block's range shaded); gaps are excluded readings.",
    "psd": "One-sided frequency-noise PSD S_ν(f) (Welch, averaged in log-spaced bands) with "
    "its confidence band; the meter's white floor 2σ²/rate from the readings' own standard "
    "deviations; the PSD with the floor removed and divided by the meter delay's "
    "|H(f)|² = sinc²(f/FSR) up to the correction limit; the fitted power law; and the β "
    "separation line [1]: noise above it sets the linewidth.",
    "allan": "Overlapping Allan, modified Allan and Hadamard deviations of the fractional "
    "frequency y = (ν − ν₀)/ν₀ at octave averaging times with at least 10 averages, with "
    "their confidence bands [2]. White FM falls as τ^-1/2, flicker FM is flat, random-walk FM "
    "and drift rise; the Hadamard deviation does not see a linear drift.",
}
NOISE_REFERENCES = (
    "G. Di Domenico, S. Schilt and P. Thomann, “Simple approach to the relation between "
    "laser frequency noise and laser line shape”, Appl. Opt. 49, 4801 (2010).",
    "W. J. Riley, “Handbook of Frequency Stability Analysis”, NIST Special Publication 1065 "
    "(2008).",
)
PHYSICS_NOTE = (
    "S_ν(f) = h₀ + h₋₁/f + h₋₂/f² (one-sided, Hz²/Hz): h₀ white FM, h₋₁ flicker FM, h₋₂ "
    "random-walk FM; the Lorentzian (white-FM) linewidth is π h₀ (FWHM). The meter's own "
    "white floor, 2σ²/rate with σ the RMS of the readings' standard deviations, is "
    "subtracted before the fit; a laser not significantly above it gets an upper limit. "
    "The interferometer's delay 1/FSR averages the frequency over that time; the PSD is "
    "divided by that filter's |H(f)|² = sinc²(f/FSR) up to the correction limit and not "
    "used above it. The photodetectors' bandwidth and any anti-aliasing filter are not "
    "corrected. The β-line linewidth is sqrt(8 ln2 A), A the area of S_ν above the line "
    "from 1/T_obs; it is a lower limit when S_ν is still above the line at the highest "
    "frequency measured, and an upper limit when the area is not significantly larger "
    "than the bands' noise alone would make (only excursions above the line count)."
)


def _number(value) -> float | None:
    """A finite float, else None (fields may be None or NaN)."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def _hz_text(value, std=None) -> str:
    """A frequency (Hz) with an SI prefix, ``value ± std`` with three significant digits
    in the std; ``n/a`` when not a number."""
    value, std = _number(value), _number(std)
    if value is None:
        return "n/a"
    scale, unit = frequency_scale(abs(value) if value else (std or 1.0))
    if std is None or not std > 0:
        return f"{significant(value / scale)} {unit}"
    return f"{with_error(value, std, scale)} {unit}"


#: a noise level (a PSD coefficient, never negative) within this many standard deviations
#: of zero is shown as an upper limit (the 97.7 % one-sided quantile, as the linewidth's)
LEVEL_LIMIT_STD = 2.0


def _level_text(value, std, unit: str) -> str:
    """A noise level: ``value ± std unit`` in exponent notation when it is significant;
    ``< value + 2 std`` (from zero when the fit came out negative) when it is not;
    ``n/a`` when not a number."""
    value, std = _number(value), _number(std)
    if value is None:
        return "n/a"
    if std is not None and value < LEVEL_LIMIT_STD * std:
        limit = max(value, 0.0) + LEVEL_LIMIT_STD * std
        return f"< {scientific(limit)} {unit} (not significant)"
    return f"{scientific_with_error(value, std)} {unit}"


def _limit_text(value, std, *, upper: bool = False, lower: bool = False) -> str:
    """A linewidth (Hz): ``< x`` as an upper limit, ``> x`` as a lower one, else ``x ± s``."""
    if _number(value) is None:
        return "n/a"
    if upper:
        return f"< {_hz_text(value)}"
    if lower:
        return f"> {_hz_text(value)}"
    return _hz_text(value, std)


def _counts_text(counts: Mapping[str, int]) -> str:
    return ", ".join(f"{name} {count}" for name, count in counts.items()) or "none"


def _input_rows(series, input_files: Mapping[str, object]) -> list[list[str]]:
    from .._version import __version__

    rows = [["wavemeter version", __version__]]
    rows += [[role, str(path)] for role, path in input_files.items() if path is not None]
    if series is None:
        return rows
    rate = "given" if series.time_column is None else f"from time column {series.time_column}"
    rows += [
        ["readings in the file", str(series.rows)],
        ["sampling rate", f"{frequency_text(series.rate_hz, 9)} ({rate})"],
        [
            "readings excluded",
            f"{series.excluded} (by reason: {_counts_text(series.excluded_counts)})",
        ],
        ["quality flags (all readings)", _counts_text(series.flag_counts)],
        [
            "unwrapped",
            f"yes, period FSR {frequency_text(series.fsr_hz)}; {series.ambiguous_steps} "
            "ambiguous step(s)"
            if series.unwrapped
            else "no: the calibration reads the absolute frequency",
        ],
        [
            "meter standard deviation σ (RMS per reading)",
            "unknown: the calibration gives none"
            if series.meter_std_hz is None
            else _hz_text(series.meter_std_hz),
        ],
    ]
    return rows


def summary_rows(result) -> list[list[str]]:
    floor = result.meter_floor_hz2_per_hz
    center = result.center_frequency_hz
    observation = _number(result.beta_observation_time_s)
    rows = [
        ["readings analysed", str(result.n_readings)],
        ["readings excluded or bridged by the analysis", str(result.n_excluded)],
        ["duration", f"{significant(result.duration_s)} s"],
        [
            "centre frequency ν₀",
            f"{center / 1e12:.9f} THz ({SPEED_OF_LIGHT_M_S / center * 1e9:.6f} nm)",
        ],
        [
            "meter floor 2σ²/rate",
            "unknown" if floor is None else f"{scientific(floor)} Hz²/Hz",
        ],
        [
            "white FM h₀",
            _level_text(result.white_fm_hz2_per_hz, result.white_fm_std_hz2_per_hz, "Hz²/Hz"),
        ],
        [
            "flicker FM h₋₁",
            _level_text(result.flicker_fm_hz2, result.flicker_fm_std_hz2, "Hz²"),
        ],
        [
            "random-walk FM h₋₂",
            _level_text(
                result.random_walk_fm_hz2_per_s, result.random_walk_fm_std_hz2_per_s, "Hz²/s"
            ),
        ],
        [
            "Lorentzian linewidth π h₀ (FWHM)",
            _limit_text(
                result.lorentzian_linewidth_hz,
                result.lorentzian_linewidth_std_hz,
                upper=result.linewidth_is_upper_limit,
            ),
        ],
        [
            "β-line linewidth (FWHM)"
            + ("" if observation is None else f", T_obs {significant(observation)} s"),
            _limit_text(
                result.beta_linewidth_hz,
                result.beta_linewidth_std_hz,
                upper=result.beta_linewidth_is_upper_limit,
                lower=result.beta_linewidth_is_lower_limit,
            ),
        ],
        [
            "linear drift",
            _level_text(result.drift_hz_per_s, result.drift_std_hz_per_s, "Hz/s"),
        ],
        [
            "delay correction up to",
            "none (FSR not given)"
            if result.delay_correction_max_hz is None
            else _hz_text(result.delay_correction_max_hz),
        ],
        ["confidence of intervals", f"{significant(100 * result.confidence)} %"],
    ]
    return rows


def _deviation_rows(result) -> list[list[str]]:
    def interval(values, bounds, k) -> str:
        low, high = np.asarray(bounds, dtype=float)[:, k]
        return f"{scientific(values[k])} [{scientific(low)}, {scientific(high)}]"

    return [
        [
            f"{tau:.3g}",
            str(int(result.n_averages[k])),
            interval(result.adev, result.adev_ci, k),
            interval(result.mdev, result.mdev_ci, k),
            interval(result.hdev, result.hdev_ci, k),
        ]
        for k, tau in enumerate(result.taus_s)
    ]


def render_noise_page(
    result,
    images: Mapping[str, bytes],
    *,
    series=None,
    input_files: Mapping[str, object] | None = None,
    warnings: Sequence[str] = (),
) -> str:
    """The complete HTML document of a frequency-noise analysis.

    Parameters
    ----------
    result : FrequencyNoise
        The analysis.
    images : mapping of str to bytes
        PNG data of each figure, by the keys of ``NOISE_FIGURE_CAPTIONS``, in page order.
    series : NoiseSeries, optional
        How the series was measured (rate, exclusions, unwrapping), shown with the inputs.
    input_files : mapping of str to str or Path, optional
        Files the analysis was made from, by role (``calibration``, ``readings``).
    warnings : sequence of str
        Warnings of the measurement, listed before the analysis's own (``result.warnings``).

    Returns
    -------
    str
    """
    created = datetime.now(UTC).isoformat(timespec="seconds")
    notes = [*warnings, *result.warnings]
    listed = (
        "<ul>" + "".join(f"<li>{html.escape(str(note))}</li>" for note in notes) + "</ul>"
        if notes
        else "<p>None.</p>"
    )
    deviations = ""
    if len(result.taus_s):
        percent = significant(100 * result.confidence)
        header = [
            "τ (s)",
            "averages",
            f"ADEV [{percent} % interval]",
            f"MDEV [{percent} % interval]",
            f"HDEV [{percent} % interval]",
        ]
        deviations = "<h2>Allan deviations of fractional frequency</h2>" + html_table(
            header, _deviation_rows(result)
        )
    references = "".join(
        f"<p>[{k}] {html.escape(text)}</p>" for k, text in enumerate(NOISE_REFERENCES, start=1)
    )
    return (
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>wavemeter frequency-noise report</title><style>{PAGE_STYLE}</style></head>"
        "<body><h1>wavemeter frequency-noise report</h1>"
        f'<div class="header"><div><h2>Inputs</h2>'
        f"{html_table(None, _input_rows(series, dict(input_files or {})))}</div>"
        f"<div><h2>Summary</h2>{html_table(None, summary_rows(result))}</div></div>"
        f"<h2>Warnings</h2>{listed}"
        + figures_html(images, NOISE_FIGURE_CAPTIONS)
        + deviations
        + f"<h2>Method</h2><p>{html.escape(PHYSICS_NOTE)}</p>"
        + "<h2>References</h2>"
        + references
        + f"<footer>Report created {created}.</footer></body></html>\n"
    )


def write_noise_report(
    result,
    out_html,
    *,
    series=None,
    frequency_hz=None,
    input_files: Mapping[str, object] | None = None,
    force: bool = False,
    dpi: int = DEFAULT_DPI,
) -> Path:
    """Draw the figures of a frequency-noise analysis and write its page, atomically.

    Parameters
    ----------
    result : FrequencyNoise
        The analysis (:func:`wavemeter.analysis.frequency_noise`).
    out_html : str or Path
        The page to write (one self-contained file).
    series : NoiseSeries, optional
        The measured series (:func:`wavemeter.jobs.noise.measure_series`): its
        frequencies are drawn, its rate, exclusions and warnings shown.
    frequency_hz : array_like, shape (N,), optional
        The series (Hz) to draw when ``series`` is not given; neither: no series figure.
    input_files : mapping of str to str or Path, optional
        Files the analysis was made from, by role; named on the page and never
        overwritten.
    force : bool
        Replace an existing page.
    dpi : int
        Resolution of the figures.

    Returns
    -------
    Path
        The page written.

    Raises
    ------
    InputError
        When the page is standard output, an input file, not a regular file, in a missing
        folder, or exists and ``force`` is false; nothing is written then.
    """
    if str(out_html) == STDOUT:
        raise InputError(
            "the noise report is a page and is not written to standard output: give a file name",
            parameter="out_html",
        )
    files = dict(input_files or {})
    check_output(
        out_html, inputs=[path for path in files.values() if path is not None], force=force
    )
    if series is not None:
        frequency_hz = series.frequency_hz
    figures = noise_figures(result, frequency_hz)
    images = {name: png_bytes(figure, dpi) for name, figure in figures.items()}
    page = render_noise_page(
        result,
        images,
        series=series,
        input_files=files,
        warnings=[str(warning) for warning in getattr(series, "warnings", ())],
    )
    target = Path(out_html)
    with atomic_path(target) as temporary:
        temporary.write_text(page, encoding="utf-8")
    return target

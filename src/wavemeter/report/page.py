"""The report's HTML page: header, tables, figures with captions, the paper's reference.

The page is self-contained (figures embedded as base64 PNG, no scripts, no external
links) and escapes every text it shows. Numbers of errors, ratios and noise carry three
significant digits; frequencies of the calibration itself carry the digits it resolves.

A cascade calibration gets a section of its stages (FSR, ports, orders, standard deviation
and error on the sweep), its hand-overs (FSR ratio and the largest the noise allows, margin
in standard deviations, predicted wrong-order rate, wrong orders on the sweep), the
coarsest stage's edge margin and the wrong orders of the evaluation readings against those
predicted (``diagnostics_["cascade"]``).
"""

from __future__ import annotations

import base64
import html
from collections.abc import Mapping
from datetime import UTC, datetime

from ..calibration.contract.base import BaseCalibrator
from ..units import SPEED_OF_LIGHT_M_S
from .formatting import (
    PHASE_COEFFICIENT_NAMES,
    port_label,
    scientific,
    scientific_with_error,
    significant,
    with_error,
)

__all__ = [
    "render_page",
    "figure_names",
    "figures_html",
    "PAPER_CITATION",
    "FIGURE_CAPTIONS",
    "THERMAL_FIGURES",
    "WIDEBAND_FIGURES",
    "wideband_record",
    "cascade_record",
    "RETRIEVAL_NAMES",
]

#: the paper the method and the figures follow, as its text states it (no venue, year or
#: DOI appear in it)
PAPER_CITATION = (
    "G. M. Hasan, M. Hasan, P. Liu, M. Rad, E. Bernier and T. J. Hall, "
    "“Optical Wavelength Meter with Machine Learning Enhanced Precision”, "
    "Photonic Technology Laboratory, University of Ottawa, and Huawei Technologies Canada"
)
PAPER_NOTE = "Venue, year and DOI are not stated in the text of the paper this package follows."
FIGURE_CAPTIONS = {
    "fringes": "Port readings of the calibration sweep (markers), the fringes of the learned "
    "map (lines) and, below, each port's residual with the detector noise estimate as a "
    "±1σ band; for a calibration set one pair per window ([1], Fig. 4b and 7a).",
    "object_space": "Object-space samples retrieved from the evaluation readings, normalised "
    "to unit source power; correct samples lie on the unit circle ([1], Fig. 4a).",
    "retrieved": "Retrieved against true frequency, the alias nearest the truth "
    "([1], Fig. 4c and 7b).",
    "residual": "Frequency error against true frequency; bottom: the learned method alone with "
    "its Cramer-Rao ±1σ band ([1], Fig. 4d and 7c; Fig. 8 across the span of a set).",
    "histogram": "Distribution of the learned method's frequency error and the Cramer-Rao "
    "bound, with the noise estimated from the calibration residual.",
    "temperature": "Frequency error against the chip temperature of each reading, the "
    "calibrated temperatures shaded; bottom: the thermal calibration alone with its "
    "Cramer-Rao ±1σ (RMS over the readings).",
    "cross_validation": "How the wide-band orders were chosen: the RMS frequency error on "
    "held-out FSR windows of each phase order P and map order J scored, against the "
    "number of fitted parameters; the chosen pair ringed.",
    "residual_phase": "Retrieved minus model phase of the calibration sweep across the "
    "band, RMS and mean per FSR window; the dashed line is the phase standard deviation "
    "the Cramer-Rao bound gives for the detector noise alone.",
}
#: figures only a calibration that needs the chip temperature has
THERMAL_FIGURES = ("temperature",)
#: figures only a wide-band calibration has (from its ``diagnostics_["wideband"]``)
WIDEBAND_FIGURES = ("cross_validation", "residual_phase")
#: phase retrieval of a calibration, by its ``retrieval`` setting (None: no such setting)
RETRIEVAL_NAMES = {
    "pinv": "pinv: x = A⁺ p, t = atan2(x₂, x₁) ([1], Eq. 24-25)",
    "ml": "ml: cone-constrained maximum likelihood, started from the pseudo-inverse",
    None: "fixed to the method (ideal-coupler projection for the conventional method)",
}
INPUT_ROLES = (("calibration", "calibration file"), ("sweep", "sweep"), ("test", "test"))

PAGE_STYLE = """
body { font-family: sans-serif; max-width: 66em; margin: 1.5em auto; padding: 0 1em;
       color: #222; line-height: 1.35; }
h1 { font-size: 1.6em; } h2 { font-size: 1.2em; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.5em 0 1.2em; }
th, td { border: 1px solid #bbb; padding: 0.2em 0.6em; text-align: right; }
th:first-child, td:first-child, table.pairs td { text-align: left; }
.header { display: flex; flex-wrap: wrap; gap: 0 2.5em; align-items: flex-start; }
figure { margin: 1.5em 0; } img { max-width: 100%; height: auto; }
figcaption { font-size: 0.9em; color: #444; }
footer, .note { font-size: 0.85em; color: #555; }
"""


def wideband_record(calibration: BaseCalibrator | None) -> Mapping | None:
    """``diagnostics_["wideband"]`` of a wide-band calibration, else None."""
    record = (getattr(calibration, "diagnostics_", None) or {}).get("wideband")
    return record if isinstance(record, Mapping) else None


def cascade_record(calibration: BaseCalibrator | None) -> Mapping | None:
    """``diagnostics_["cascade"]`` of a cascade calibration, else None."""
    record = (getattr(calibration, "diagnostics_", None) or {}).get("cascade")
    return record if isinstance(record, Mapping) else None


def figure_names(calibration: BaseCalibrator | None = None) -> list[str]:
    """The figures of a calibration's report, in page order (default: those of every
    calibration; a calibration that needs the chip temperature adds ``THERMAL_FIGURES``,
    a wide-band one ``WIDEBAND_FIGURES``)."""
    thermal = calibration is not None and "temperature_k" in calibration.requires
    wideband = wideband_record(calibration) is not None
    return [
        name
        for name in FIGURE_CAPTIONS
        if (thermal or name not in THERMAL_FIGURES) and (wideband or name not in WIDEBAND_FIGURES)
    ]


def html_table(header: list[str] | None, rows: list[list[str]]) -> str:
    head = ""
    if header:
        head = "<tr>" + "".join(f"<th>{html.escape(cell)}</th>" for cell in header) + "</tr>"
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(cell)}</td>" for cell in row) + "</tr>" for row in rows
    )
    kind = "" if header else ' class="pairs"'
    return f"<table{kind}>{head}{body}</table>"


def _mhz(value_hz: float) -> str:
    return significant(value_hz / 1e6)


def _retrieval(calibration: BaseCalibrator) -> str:
    single = calibration.windows_[0] if hasattr(calibration, "windows_") else calibration
    setting = single.get_params().get("retrieval")
    return RETRIEVAL_NAMES.get(setting, str(setting))


def _input_rows(input_files: Mapping[str, object]) -> list[list[str]]:
    from .._version import __version__

    rows = [["wavemeter version", __version__]]
    for role, name in INPUT_ROLES:
        given = input_files.get(role)
        if given is not None:
            rows.append([name, str(given)])
        elif role == "test":
            rows.append([name, "none: evaluated on the sweep"])
    return rows


def _calibration_rows(calibration: BaseCalibrator, summary: dict) -> list[list[str]]:
    low, high = calibration.span_hz_
    center = calibration.center_hz_
    design = calibration.get_params()["fsr_hz"]
    cascade = cascade_record(calibration) is not None
    rows = [
        ["method", calibration.method_label],
        ["phase retrieval", _retrieval(calibration)],
        [
            "design FSRs, coarsest first (GHz)" if cascade else "design FSR (GHz)",
            ", ".join(f"{value / 1e9:.6g}" for value in design)
            if cascade
            else f"{design / 1e9:.6g}",
        ],
        [
            "fitted FSR of the finest stage (GHz)" if cascade else "fitted FSR (GHz)",
            f"{calibration.fsr_hz_ / 1e9:.9g}",
        ],
        ["centre (THz)", f"{center / 1e12:.9g}"],
        ["centre vacuum wavelength (nm)", f"{SPEED_OF_LIGHT_M_S / center * 1e9:.6f}"],
        ["sweep span (GHz)", f"{(high - low) / 1e9:.6g}"],
        ["ports", ", ".join(port_label(name) for name in calibration.port_names_)],
        ["calibration samples", str(calibration.n_samples_)],
        ["calibration RMS error (MHz)", _mhz(calibration.calibration_rms_hz_)],
    ]
    noise = summary.get("noise_std_w")
    if noise is not None:
        source = f"{summary['noise_from']} fit residual"
        if cascade:
            source = "the finest stage's fit residual"
        elif summary["noise_from"] != calibration.method_label:
            source += " on the same sweep"
        rows.append(["detector noise estimate (W)", f"{scientific(noise)} ({source})"])
    if hasattr(calibration, "windows_"):
        rows.append(["windows (one FSR each)", str(len(calibration.windows_))])
    return rows + _thermal_rows(calibration) + _wideband_rows(calibration)


def _thermal_rows(calibration: BaseCalibrator) -> list[list[str]]:
    """The thermal rates with their standard errors, the reference temperature, the
    calibrated temperatures and the bias rates they resolve (``diagnostics_["thermal"]``);
    none for a calibration without that record."""
    thermal = (getattr(calibration, "diagnostics_", None) or {}).get("thermal")
    if not isinstance(thermal, Mapping):
        return []
    low, high = thermal["temperature_range_k"]
    clusters = ", ".join(f"{value:.6g}" for value in thermal.get("temperatures_k") or [])
    unambiguous = thermal.get("unambiguous_phase_rate_rad_per_k")
    return [
        [
            "bias phase rate (rad/K)",
            with_error(thermal["thermal_phase_rad_per_k"], thermal["thermal_phase_std_rad_per_k"]),
        ],
        [
            "fringe shift (GHz/K, to lower frequency on heating)",
            with_error(thermal["fringe_shift_hz_per_k"], thermal["fringe_shift_std_hz_per_k"], 1e9),
        ],
        [
            "delay rate (1/K)",
            f"{scientific(thermal['thermal_delay_per_k'])} ± "
            f"{scientific(thermal['thermal_delay_std_per_k'])}",
        ],
        ["reference temperature (K)", f"{thermal['reference_temperature_k']:.6g}"],
        [
            "calibrated temperatures (K)",
            f"{low:.6g} to {high:.6g}" + (f" (clusters at {clusters})" if clusters else ""),
        ],
        [
            "bias rate unambiguous within (rad/K)",
            "any rate (the temperature changed continuously)"
            if unambiguous is None
            else f"±{significant(unambiguous)}",
        ],
    ]


def _wideband_rows(calibration: BaseCalibrator) -> list[list[str]]:
    """The orders, parameter count and phase coefficients (with standard errors) of a
    wide-band calibration (``diagnostics_["wideband"]``); none for other calibrations."""
    record = wideband_record(calibration)
    if record is None:
        return []
    rows = [
        ["phase order P", str(record["phase_order"])],
        ["map order J", str(record["map_order"])],
        ["fitted parameters", str(record["n_parameters"])],
    ]
    errors = record.get("phase_coefficients_std_s") or [None] * len(record["phase_coefficients_s"])
    for order, (value, error) in enumerate(
        zip(record["phase_coefficients_s"], errors, strict=True), start=1
    ):
        unit = "s" if order == 1 else f"s^{order}"
        name = PHASE_COEFFICIENT_NAMES.get(order, f"order {order}")
        rows.append([f"phase c{order}, {name} ({unit})", scientific_with_error(value, error)])
    return rows


def _wideband_html(calibration: BaseCalibrator) -> str:
    """The wide-band section: the candidates the orders were chosen from (the
    cross-validation curve as a table) and the residual phase across the band."""
    record = wideband_record(calibration)
    if record is None:
        return ""
    orders = record["orders"]
    candidates = orders["candidates"]
    if candidates:
        header = ["phase order P", "map order J", "parameters", "held-out RMS (MHz)", "chosen"]
        rows = [
            [
                str(candidate["phase_order"]),
                str(candidate["map_order"]),
                str(candidate["parameters"]),
                _mhz(candidate["cv_rms_hz"]),
                "chosen" if candidate["chosen"] else "",
            ]
            for candidate in candidates
        ]
        choice = f"<p>{html.escape(str(orders['reason']))}.</p>" + html_table(header, rows)
    else:
        choice = f"<p>No cross-validation: {html.escape(str(orders['reason']))}.</p>"
    residual = record["residual_phase"]
    worst = max(residual, key=lambda row: row["rms_rad"])
    lowest = min(row["rms_rad"] for row in residual)
    text = (
        f"Residual phase RMS per FSR window: {significant(lowest * 1e3)} to "
        f"{significant(worst['rms_rad'] * 1e3)} mrad over {len(residual)} windows; the "
        f"largest in the window at {worst['center_hz'] / 1e12:.6f} THz (mean "
        f"{significant(worst['mean_rad'] * 1e3)} mrad, {worst['readings']} readings)."
    )
    return "<h2>Wide band: orders and residual phase</h2>" + choice + f"<p>{html.escape(text)}</p>"


def _cascade_html(calibration: BaseCalibrator, summary: dict) -> str:
    """The cascade section: its stages, its hand-overs on the sweep, the coarsest stage's
    edge margin and the wrong orders of the evaluation readings; empty for other
    calibrations."""
    record = cascade_record(calibration)
    if record is None:
        return ""
    design = calibration.get_params()["fsr_hz"]
    stage_header = [
        "stage",
        "ports",
        "design FSR (GHz)",
        "fitted FSR (GHz)",
        "phase order P",
        "map order J",
        "median std (MHz)",
        "RMS error on the sweep (MHz)",
        "z-score spread",
    ]
    stage_rows = [
        [
            str(stage["stage"]),
            ", ".join(port_label(name) for name in stage["ports"]),
            f"{design[index] / 1e9:.6g}",
            f"{stage['fsr_hz'] / 1e9:.9g}",
            str(stage["phase_order"]),
            str(stage["map_order"]),
            _mhz(stage["median_std_hz"]),
            _mhz(stage["rms_hz"]),
            significant(stage["z_std"]),
        ]
        for index, stage in enumerate(record["stages"])
    ]
    handover_header = [
        "hand-over",
        "FSR ratio",
        "largest usable ratio",
        "margin (std, median)",
        "worst margin (std)",
        "predicted wrong-order rate",
        "expected wrong on the sweep",
        "wrong on the sweep",
    ]
    handover_rows = [
        [
            f"stage {handover['from_stage']} to {handover['to_stage']}",
            significant(handover["ratio"]),
            significant(handover["largest_usable_ratio"]),
            significant(handover["margin_std"]),
            significant(handover["worst_margin_std"]),
            scientific(handover["predicted_rate"]),
            scientific(handover["expected_wrong"]),
            str(handover["wrong_on_sweep"]),
        ]
        for handover in record["handovers"]
    ]
    text = (
        "Each stage picks the fringe order of the next; a hand-over's margin is half the "
        "finer stage's FSR over the standard deviation of the two stages' difference, and "
        "the largest usable ratio the FSR ratio at which the sweep's noise would make the "
        f"wrong-order rate {calibration.get_params()['max_order_error']:g} (max_order_error, "
        "above which a reading is flagged ORDER_AMBIGUOUS). The coarsest stage's phase is "
        f"unique {significant(record['edge_margin_std'])} of its standard deviations beyond "
        "the band's ends (edge margin)."
    )
    orders = summary.get("order_errors")
    if orders is not None:
        text += (
            f" On the {summary['evaluated_on']}: {orders['wrong_orders']} of "
            f"{orders['readings']} readings off by half the finest stage's FSR or more, "
            f"{scientific(orders['expected_wrong_orders'])} expected from their "
            f"order_error_probability; {orders['flagged_order_ambiguous']} flagged "
            f"ORDER_AMBIGUOUS ({orders['wrong_orders_flagged']} of the wrong ones)."
        )
    text += (
        " A cascade is shown alone: no other method reads absolute frequency from the "
        "readings of its stages."
    )
    return (
        "<h2>Cascade: stages and hand-overs</h2>"
        + html_table(stage_header, stage_rows)
        + html_table(handover_header, handover_rows)
        + f"<p>{html.escape(text)}</p>"
    )


#: SI suffix of a diagnostics key -> (unit shown, SI value per unit, exponent notation)
#: temperatures (``_k``, not rates ``_per_k``) with the digits a temperature needs
_KEY_UNITS = {
    "_w": ("W", 1.0, True),
    "_hz": ("GHz", 1e9, False),
    "_s": ("s", 1.0, True),
    "_k": ("K", 1.0, None),
}
#: digits of a temperature in K (mK resolution near room temperature)
TEMPERATURE_DIGITS = 6
#: diagnostics shown in a table of their own rather than among the diagnostics
_SHOWN_ELSEWHERE = {"thermal", "wideband", "cascade"}


def _key_unit(key: str):
    if key.endswith("_per_k"):
        return None
    return next(((s, *unit) for s, unit in _KEY_UNITS.items() if key.endswith(s)), None)


def _key_title(key: str) -> str:
    """``"fringe_amplitude_w"`` -> ``"fringe amplitude (W)"``."""
    unit = _key_unit(key)
    if unit is None:
        return key.replace("_", " ")
    suffix, name, _, _ = unit
    return f"{key[: -len(suffix)].replace('_', ' ')} ({name})"


def _value_text(value, key: str = "") -> str:
    """A diagnostics value in the unit of its key: powers and times in exponent notation,
    frequencies in GHz and other floats with three significant digits; containers item by
    item."""
    if isinstance(value, float):
        unit = _key_unit(key)
        if unit is None:
            return significant(value)
        _, _, scale, exponent = unit
        if exponent is None:
            return f"{value / scale:.{TEMPERATURE_DIGITS}g}"
        return scientific(value / scale) if exponent else significant(value / scale)
    if isinstance(value, Mapping):
        return "; ".join(f"{_key_title(k)}: {_value_text(item, k)}" for k, item in value.items())
    if isinstance(value, (list, tuple)):
        return ", ".join(_value_text(item, key) for item in value) or "none"
    return str(value)


def _records_table(records: list[Mapping]) -> str:
    """A table of records (e.g. one per port) with the union of their keys as columns."""
    keys = list(dict.fromkeys(key for record in records for key in record))
    rows = [[_value_text(record.get(key, ""), key) for key in keys] for record in records]
    return html_table([_key_title(key) for key in keys], rows)


def _warning_row(note) -> list[str]:
    """A calibration warning: its cause, then its message and remedy."""
    if not isinstance(note, Mapping):
        return ["warning", _value_text(note)]
    text = " ".join(str(note[part]) for part in ("message", "remedy") if note.get(part))
    return [f"warning ({note.get('cause', 'other')})", text]


def _diagnostics_html(calibration: BaseCalibrator) -> str:
    """The calibration's ``diagnostics_`` when it has any: scalar items as rows, lists of
    records (ports) as tables, warnings with their cause, message and remedy (the thermal
    and wide-band records are in the calibration's table and a section of their own)."""
    diagnostics = getattr(calibration, "diagnostics_", None)
    if not diagnostics:
        return ""
    if not isinstance(diagnostics, Mapping):
        diagnostics = {"diagnostics": diagnostics}
    rows, tables = [], []
    for key, value in diagnostics.items():
        if key in _SHOWN_ELSEWHERE:
            continue
        is_records = (
            isinstance(value, list) and value and all(isinstance(v, Mapping) for v in value)
        )
        if key == "warnings" and isinstance(value, list):
            rows += [_warning_row(note) for note in value] or [["warnings", "none"]]
        elif is_records:
            tables.append(f"<h3>{html.escape(_key_title(key))}</h3>" + _records_table(value))
        else:
            rows.append([_key_title(key), _value_text(value, key)])
    return "<h2>Diagnostics of the calibration</h2>" + html_table(None, rows) + "".join(tables)


def _window_rows(calibration: BaseCalibrator) -> list[list[str]]:
    rows = []
    for index, window in enumerate(calibration.windows_):
        noise = getattr(window, "noise_std_w_", None)
        rows.append(
            [
                str(index),
                f"{window.center_hz_ / 1e12:.6f}",
                f"{window.fsr_hz_ / 1e9:.6f}",
                str(window.n_samples_),
                _mhz(window.calibration_rms_hz_),
                "" if noise is None else scientific(noise),
            ]
        )
    return rows


def _error_rows(summary: dict) -> list[list[str]]:
    crlb = summary["crlb_rms_hz"]
    rows = [
        [
            name,
            _mhz(stats["rms_hz"]),
            _mhz(stats["max_hz"]),
            _mhz(stats["p95_hz"]),
            _mhz(stats["p99_hz"]),
            significant(stats["rms_hz"] / crlb),
        ]
        for name, stats in summary["methods"].items()
    ]
    rows.append(["CRLB", _mhz(crlb), "", "", "", significant(1.0)])
    return rows


def _adjacent_html(adjacent: dict | str) -> str:
    if isinstance(adjacent, str):
        return f"<p>Adjacent-window evaluation not available: {html.escape(adjacent)}</p>"
    header = [
        "window",
        "centre (THz)",
        "own RMS (MHz)",
        "own max (MHz)",
        "adjacent RMS (MHz)",
        "adjacent max (MHz)",
        "conventional adjacent max (MHz)",
    ]
    rows = [
        [
            str(entry["window"]),
            f"{entry['center_hz'] / 1e12:.6f}",
            _mhz(entry["own"]["rms_hz"]),
            _mhz(entry["own"]["max_hz"]),
            _mhz(entry["adjacent"]["rms_hz"]),
            _mhz(entry["adjacent"]["max_hz"]),
            _mhz(entry["conventional_adjacent"]["max_hz"]),
        ]
        for entry in adjacent["windows"]
    ]
    return (
        "<h2>Maps applied to the neighbouring FSRs ([1], Fig. 9)</h2>"
        f"<p>Adjacent over own RMS: {significant(adjacent['degradation_rms'])}.</p>"
        + html_table(header, rows)
    )


def _comparison_note(summary: dict) -> str:
    """The calibration warnings of the comparison method's fit, which the page reports
    instead of the command line (they are about the comparison, not the calibration), or
    why it could not be fitted."""
    error = summary.get("comparison_error")
    if error:
        return (
            '<p class="note">The comparison method could not be fitted on the same sweep, so '
            f"the calibration is shown alone: {html.escape(error)}</p>"
        )
    notes = summary.get("comparison_warnings") or []
    if not notes:
        return ""
    items = "".join(f"<li>{html.escape(note)}</li>" for note in notes)
    return (
        f'<p class="note">The comparison ({html.escape(str(summary.get("comparison")))}, '
        f'fitted on the same sweep) warned:</p><ul class="note">{items}</ul>'
    )


def figures_html(images: Mapping[str, bytes], captions: Mapping[str, str]) -> str:
    """``<figure>`` elements with each PNG embedded (base64) and its caption, in the order
    of ``images`` (name -> PNG data); ``captions`` by the same names."""
    return "".join(
        f'<figure id="figure-{html.escape(name)}"><img alt="{html.escape(name)} figure" '
        f'src="data:image/png;base64,{base64.b64encode(png).decode("ascii")}">'
        f"<figcaption>{html.escape(captions[name])}</figcaption></figure>"
        for name, png in images.items()
    )


def render_page(
    calibration: BaseCalibrator,
    summary: dict,
    images: Mapping[str, bytes],
    input_files: Mapping[str, object],
) -> str:
    """The complete HTML document.

    Parameters
    ----------
    calibration : BaseCalibrator
        The fitted calibration under report.
    summary : dict
        Numbers from :func:`wavemeter.report.content.report_content`.
    images : mapping of str to bytes
        PNG data of each figure, by the keys of ``FIGURE_CAPTIONS``, in page order.
    input_files : mapping of str to str or Path
        Files the report was made from, by role: ``calibration``, ``sweep``, ``test``.

    Returns
    -------
    str
    """
    created = datetime.now(UTC).isoformat(timespec="seconds")
    windows = ""
    if hasattr(calibration, "windows_"):
        header = ["window", "centre (THz)", "FSR (GHz)", "samples", "RMS (MHz)", "noise (W)"]
        windows = "<h2>Windows of the set</h2>" + html_table(header, _window_rows(calibration))
    errors_header = ["method", "RMS (MHz)", "max (MHz)", "p95 (MHz)", "p99 (MHz)", "RMS / CRLB"]
    adjacent = _adjacent_html(summary["adjacent"]) if "adjacent" in summary else ""
    return (
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>wavemeter calibration report</title><style>{PAGE_STYLE}</style></head><body>"
        "<h1>wavemeter calibration report</h1>"
        f'<div class="header"><div><h2>Inputs</h2>{html_table(None, _input_rows(input_files))}'
        "</div>"
        f"<div><h2>Calibration</h2>{html_table(None, _calibration_rows(calibration, summary))}"
        "</div></div>"
        + _diagnostics_html(calibration)
        + _wideband_html(calibration)
        + _cascade_html(calibration, summary)
        + windows
        + f"<h2>Frequency error on the {html.escape(summary['evaluated_on'])} "
        f"({summary['samples']} readings)</h2>"
        + html_table(errors_header, _error_rows(summary))
        + '<p class="note">RMS / CRLB near 1.00: limited by detector noise. The bound uses the '
        "noise estimated from the calibration residual and the learned map as the true one.</p>"
        + _comparison_note(summary)
        + adjacent
        + figures_html(images, FIGURE_CAPTIONS)
        + "<h2>Reference</h2>"
        f"<p>[1] {html.escape(PAPER_CITATION)}. {html.escape(PAPER_NOTE)}</p>"
        f"<footer>Report created {created}.</footer>"
        "</body></html>\n"
    )

"""The report's HTML page: header, tables, figures with captions, the paper's reference.

The page is self-contained (figures embedded as base64 PNG, no scripts, no external
links) and escapes every text it shows. Numbers of errors, ratios and noise carry three
significant digits; frequencies of the calibration itself carry the digits it resolves.

What is specific to a method comes from the calibration's description (``summary()``:
its values with labels, its notes and tables, its parts) and from the checks it makes on
the evaluation readings; the page renders them without knowing the method.
"""

from __future__ import annotations

import base64
import html
from collections.abc import Mapping
from datetime import UTC, datetime

import numpy as np

from ..calibration.contract.base import COMMON_DIAGNOSTICS, BaseCalibrator
from ..calibration.contract.flags import flag_summary
from ..calibration.contract.summary import Table, value_text
from ..units import SPEED_OF_LIGHT_M_S
from .formatting import port_label, scientific, significant

__all__ = [
    "render_page",
    "figure_names",
    "figures_html",
    "PAPER_CITATION",
    "FIGURE_CAPTIONS",
    "THERMAL_FIGURES",
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
}
#: figures only a calibration that needs the chip temperature has
THERMAL_FIGURES = ("temperature",)
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


def figure_names(calibration: BaseCalibrator | None = None) -> list[str]:
    """The figures of a calibration's report, in page order (default: those of every
    calibration; a calibration that needs the chip temperature adds ``THERMAL_FIGURES``,
    and every calibration the figures it declares, ``report_figures``)."""
    thermal = calibration is not None and "temperature_k" in calibration.requires
    names = [name for name in FIGURE_CAPTIONS if thermal or name not in THERMAL_FIGURES]
    if calibration is not None:
        names += [data.name for data in calibration.report_figures()]
    return names


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
    """The phase retrieval of a calibration, or of its first part (a set's windows)."""
    parts = calibration.parts()
    single = parts[0].calibration if parts else calibration
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


#: values of a description shown in the calibration's first rows, not among the others
_HEADER_VALUES = ("fsr_hz", "design_fsr_hz", "center_hz", "calibration_rms_hz", "noise_std_w")


def _calibration_rows(calibration: BaseCalibrator, report, summary: dict) -> list[list[str]]:
    """The calibration's table: what every calibration has, then the values, notes and
    part count of its description (``summary()``)."""
    low, high = calibration.span_hz_
    center = calibration.center_hz_
    design = calibration.get_params()["fsr_hz"]
    several = np.ndim(design) == 1
    parts = calibration.parts()
    rows = [
        ["method", calibration.method_label],
        ["phase retrieval", _retrieval(calibration)],
        [
            "design FSRs, coarsest first (GHz)" if several else "design FSR (GHz)",
            ", ".join(f"{value / 1e9:.6g}" for value in np.atleast_1d(design)),
        ],
        [
            f"fitted FSR of the finest {parts[-1].kind} (GHz)"
            if several and parts
            else "fitted FSR (GHz)",
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
        if summary["noise_from"] != calibration.method_label:
            source += " on the same sweep"
        rows.append(["detector noise estimate (W)", f"{scientific(noise)} ({source})"])
    if parts:
        rows.append([f"{parts[0].kind}s", str(len(parts))])
    for name, value in report.values.items():
        if name not in _HEADER_VALUES:
            rows.append([value.label or name.replace("_", " "), value_text(value)])
    rows += [["note", note] for note in report.notes]
    return rows


def _table_html(table: Table | dict, level: str = "h3") -> str:
    """A table of a description or a check, with its title and text."""
    if isinstance(table, Table):
        table = table.as_dict()
    rows = [[_cell(cell) for cell in row] for row in table["rows"]]
    text = f"<p>{html.escape(table['text'])}</p>" if table.get("text") else ""
    heading = f"<{level}>{html.escape(table['title'])}</{level}>"
    return heading + html_table(list(table["columns"]), rows) + text


def _cell(cell) -> str:
    return significant(cell) if isinstance(cell, float) else str(cell)


def _description_html(report) -> str:
    """The tables a calibration adds to its description (stages, hand-overs, orders)."""
    if not report.tables:
        return ""
    return "<h2>Model</h2>" + "".join(_table_html(table) for table in report.tables)


def _checks_html(summary: dict) -> str:
    """The checks the calibration made of itself on the evaluation readings."""
    parts = []
    for check in summary.get("checks") or []:
        text = f"<p>{html.escape(check['text'])}</p>" if check["text"] else ""
        table = "" if check["table"] is None else _table_html(check["table"], "h3")
        parts.append(f"<h2>{html.escape(check['title'])}</h2>{text}{table}")
    return "".join(parts)


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
    item; an absent value (a test not run, a temperature not recorded) and flags in words."""
    if value is None:
        return "not recorded" if key.startswith("temperature") else "not computed"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, str) and key.endswith(("method", "cause")):
        return value.replace("_", " ")  # a name of the package's (second_difference)
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
    method's own records are shown by its description)."""
    diagnostics = calibration.diagnostics_
    if not diagnostics:
        return ""
    rows, tables = [], []
    for key, value in diagnostics.items():
        if key not in COMMON_DIAGNOSTICS:
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


def _parts_html(calibration: BaseCalibrator) -> str:
    """One row per part of a composite (a set's windows, a cascade's stages)."""
    parts = calibration.parts()
    if not parts:
        return ""
    header = ["part", "centre (THz)", "FSR (GHz)", "samples", "RMS (MHz)", "noise (W)"]
    rows = []
    for part in parts:
        single = part.calibration
        noise = single.summary().values.get("noise_std_w")
        rows.append(
            [
                part.label,
                f"{single.center_hz_ / 1e12:.6f}",
                f"{single.fsr_hz_ / 1e9:.6f}",
                str(single.n_samples_),
                _mhz(single.calibration_rms_hz_),
                "" if noise is None else scientific(noise.value),
            ]
        )
    return f"<h2>The {parts[0].kind}s</h2>" + html_table(header, rows)


def _error_rows(summary: dict) -> list[list[str]]:
    """Each method's absolute error (as ``wavemeter evaluate`` prints it), its error
    modulo its FSR, the share of gross errors, and the bound."""
    crlb = summary["crlb_rms_hz"]
    rows = [
        [
            name,
            _mhz(stats["rms_abs_hz"]),
            _mhz(stats["max_abs_hz"]),
            _mhz(stats["p95_abs_hz"]),
            _mhz(stats["p99_abs_hz"]),
            "" if crlb is None else significant(stats["rms_abs_hz"] / crlb),
            _mhz(stats["rms_mod_fsr_hz"]),
            "" if crlb is None else significant(stats["rms_mod_fsr_hz"] / crlb),
            f"{100 * stats['gross_error_fraction']:.3g} %",
        ]
        for name, stats in summary["methods"].items()
    ]
    if crlb is not None:
        rows.append(["CRLB", _mhz(crlb), "", "", "", significant(1.0), "", "", ""])
    return rows


def _flag_note(summary: dict) -> str:
    """Each method's flags on the evaluation readings, counted as ``measure`` counts them."""
    samples = summary["samples"]
    lines = [
        f"{name}: {flag_summary(figures['flagged'], figures['flagged_readings'], samples)}"
        for name, figures in summary["methods"].items()
        if figures["flagged_readings"]
    ]
    if not lines:
        return ""
    return f'<p class="note">Flags: {html.escape("; ".join(lines))}.</p>'


def _unread_note(summary: dict) -> str:
    """How many evaluation readings a method could not read, by flag (none: nothing)."""
    unread = summary.get("unread") or {}
    if not unread:
        return ""
    parts = [
        f"{name}: {', '.join(f'{count} {flag}' for flag, count in counts.items())}"
        for name, counts in unread.items()
    ]
    return (
        '<p class="note">Readings a method could not read have no error and are left out '
        f"of these numbers ({html.escape('; '.join(parts))}).</p>"
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
        PNG data of each figure, by the keys of ``FIGURE_CAPTIONS`` and of the
        calibration's own figures (their captions in ``summary["captions"]``), in page
        order.
    input_files : mapping of str to str or Path
        Files the report was made from, by role: ``calibration``, ``sweep``, ``test``.

    Returns
    -------
    str
    """
    created = datetime.now(UTC).isoformat(timespec="seconds")
    report = calibration.summary()
    errors_header = [
        "method",
        "RMS (MHz)",
        "max (MHz)",
        "p95 (MHz)",
        "p99 (MHz)",
        "RMS / CRLB",
        "RMS mod FSR (MHz)",
        "RMS mod FSR / CRLB",
        "off by half an FSR or more",
    ]
    captions = {**FIGURE_CAPTIONS, **summary.get("captions", {})}
    return (
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>wavemeter calibration report</title><style>{PAGE_STYLE}</style></head><body>"
        "<h1>wavemeter calibration report</h1>"
        f'<div class="header"><div><h2>Inputs</h2>{html_table(None, _input_rows(input_files))}'
        "</div>"
        "<div><h2>Calibration</h2>"
        f"{html_table(None, _calibration_rows(calibration, report, summary))}</div></div>"
        + _diagnostics_html(calibration)
        + _description_html(report)
        + _parts_html(calibration)
        + f"<h2>Frequency error on the {html.escape(summary['evaluated_on'])} "
        f"({summary['samples']} readings)</h2>"
        + html_table(errors_header, _error_rows(summary))
        + '<p class="note">RMS / CRLB near 1.00: limited by detector noise. The bound uses the '
        "noise estimated from the calibration residual and the learned map as the true one.</p>"
        + _unread_note(summary)
        + _flag_note(summary)
        + _comparison_note(summary)
        + _checks_html(summary)
        + figures_html(images, captions)
        + "<h2>Reference</h2>"
        f"<p>[1] {html.escape(PAPER_CITATION)}. {html.escape(PAPER_NOTE)}</p>"
        f"<footer>Report created {created}.</footer>"
        "</body></html>\n"
    )

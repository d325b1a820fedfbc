"""An HTML report of a calibration: the paper's figures and error tables in one page.

The page is self-contained (figures embedded as base64 PNG, no external links) and the PNG
files are written beside it; every file is written atomically and only after all figures
have been drawn, so a failure leaves no partial output.

The calibration is compared with the other method (learned against conventional) fitted
on the same sweep, and evaluated on the test readings (or on the sweep when there are
none): fringes and fitted model (paper Fig. 4b / 7a), object space (Fig. 4a), retrieved
frequency and residual (Figs. 4c,d / 7b,c), error histogram against the Cramer-Rao bound,
and for calibration sets the residual across the whole span (Fig. 8) and the
adjacent-window evaluation (Fig. 9).
"""

from __future__ import annotations

import base64
import html
import io
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from scipy import linalg

from ..analysis.evaluation import adjacent_evaluation
from ..analysis.metrics import error_summary_hz, frequency_error_hz
from ..atomic import atomic_path
from ..calibration.base import BaseCalibrator
from ..calibration.baselines import ConventionalCalibrator
from ..calibration.learned import Calibrator
from ..calibration.set import CalibrationSet
from ..exceptions import InputError
from ..model.cone import SQRT2, cone_vectors, delay_phase_rad, wrap_phase_rad
from ..validation import check_fitted, check_frequency, check_powers

__all__ = [
    "write_report",
    "report_content",
    "comparison_calibration",
    "crlb_per_reading_hz",
    "retrieved_frequency_hz",
]

DEFAULT_DPI = 90
MODEL_POINTS = 1000
#: half width, in FSRs, of the stretch of a wide sweep shown in the fringe figure
FRINGE_HALF_WIDTH_FSR = 1.5
SPEED_OF_LIGHT_M_S = 299_792_458.0
FIGURE_CAPTIONS = {
    "fringes": "Port readings of the calibration sweep (markers) and the fringes of the "
    "learned map (lines), paper Fig. 4b / 7a.",
    "object_space": "Object-space samples retrieved from the evaluation readings, normalised "
    "to unit source power; correct samples lie on the unit circle (paper Fig. 4a).",
    "retrieved": "Retrieved against true frequency, the alias nearest the truth "
    "(paper Fig. 4c / 7b).",
    "residual": "Frequency error against true frequency; bottom: the learned method alone with "
    "its Cramer-Rao band (paper Fig. 4d / 7c; Fig. 8 across the span of a set).",
    "histogram": "Distribution of the learned method's frequency error and the Cramer-Rao "
    "bound (noise estimated from the calibration residual).",
}


@dataclass(frozen=True)
class _Readings:
    frequency_hz: np.ndarray
    powers_w: np.ndarray
    monitor_w: np.ndarray | None


def _readings(table, role: str, ports: int) -> _Readings:
    """Validated arrays of a table: ``frequency_hz`` or ``x_hz`` (N,), ``powers_w`` (N, n)."""
    frequency = getattr(table, "frequency_hz", None)
    if frequency is None:
        frequency = getattr(table, "x_hz", None)
    if frequency is None or not hasattr(table, "powers_w"):
        raise InputError(
            f"{role} must have attributes powers_w (N, n) and frequency_hz or x_hz (N,), "
            f"got {type(table).__name__} without them"
        )
    try:
        powers = check_powers(table.powers_w, min_samples=1, ports=ports)
        frequency = check_frequency(frequency, powers.shape[0], name=f"{role} frequency")
    except ValueError as exc:
        raise InputError(f"{role}: {exc}") from exc
    monitor = getattr(table, "monitor_w", None)
    return _Readings(frequency, powers, None if monitor is None else np.asarray(monitor, float))


def _check_inside(calibration: CalibrationSet, frequency_hz: np.ndarray, role: str) -> None:
    low, high = calibration.covered_hz()
    outside = (frequency_hz < low) | (frequency_hz > high)
    if outside.any():
        raise InputError(
            f"{role}: {int(outside.sum())} readings lie outside the calibration set's span "
            f"{low / 1e12:.6f} to {high / 1e12:.6f} THz (first at "
            f"{frequency_hz[outside][0] / 1e12:.6f} THz); a set has no map there: drop them"
        )


def _is_learned(calibration: BaseCalibrator) -> bool:
    return isinstance(_central(calibration), Calibrator)


def _label(calibration: BaseCalibrator) -> str:
    return calibration.method_label


def comparison_calibration(
    calibration: BaseCalibrator,
    powers_w,
    frequency_hz,
    power_monitor_w=None,
    port_phases_rad=None,
) -> BaseCalibrator:
    """The other method fitted on the same sweep: learned for any other, else conventional.

    Parameters
    ----------
    calibration : BaseCalibrator
        The fitted calibration under report; a :class:`CalibrationSet` is compared with a
        set of the other window method.
    powers_w : array_like, shape (N, n)
        Calibration sweep readings (W).
    frequency_hz : array_like, shape (N,)
        Their known frequencies (Hz).
    power_monitor_w : None or array_like, shape (N,)
        Source-power monitor (W), used by the learned method.
    port_phases_rad : None or array_like, shape (n,)
        Nominal port phases for a conventional comparison; default those of
        ``calibration`` when it has them, else equally spaced.

    Returns
    -------
    BaseCalibrator
        Fitted with the design FSR of ``calibration``.
    """
    design = calibration.fsr_hz
    own = _central(calibration)
    phases = own.get_params().get("port_phases_rad") if port_phases_rad is None else port_phases_rad
    if _is_learned(calibration):
        fitted = ConventionalCalibrator(fsr_hz=design, port_phases_rad=phases)
    else:
        fitted = Calibrator(fsr_hz=design)
    if isinstance(calibration, CalibrationSet):
        fitted = CalibrationSet(design, calibration.fsr_tolerance, window=fitted)
    return fitted.fit(powers_w, frequency_hz, power_monitor_w, calibration.port_names_)


def retrieved_frequency_hz(calibration: BaseCalibrator, powers_w, frequency_hz) -> np.ndarray:
    """Frequency (Hz) each reading is retrieved at, the alias nearest its true frequency.

    A calibration set is given the true frequency as the coarse value.
    """
    truth = np.asarray(frequency_hz, dtype=float)
    if isinstance(calibration, CalibrationSet):
        return calibration.predict(powers_w, coarse_hz=truth)
    predicted = calibration.predict(powers_w)
    return truth + frequency_error_hz(predicted, truth, calibration.fsr_hz_)


def _window_rows(calibration: BaseCalibrator, frequency_hz: np.ndarray):
    """(single calibrator, rows) pairs covering the readings: windows of a set, or all."""
    if not isinstance(calibration, CalibrationSet):
        return [(calibration, np.ones(frequency_hz.size, dtype=bool))]
    index = calibration.window_index(frequency_hz)
    return [(calibration.windows_[k], index == k) for k in np.unique(index)]


def crlb_per_reading_hz(calibration: BaseCalibrator, powers_w, frequency_hz) -> np.ndarray | None:
    """Per-reading Cramer-Rao standard deviation (Hz) under a learned calibration's model.

    The map, FSR and noise (``noise_std_w_``, from the calibration residual) are the fitted
    ones and the phase that of the true frequency
    (:meth:`wavemeter.Calibrator.frequency_std_hz` at that phase).

    Parameters
    ----------
    calibration : Calibrator or CalibrationSet
        A learned calibration (a set: of learned windows, each reading under its window).
    powers_w : array_like, shape (N, n)
    frequency_hz : array_like, shape (N,)
        True frequency of each reading (Hz).

    Returns
    -------
    ndarray, shape (N,), Hz, or None when ``calibration`` is not learned.
    """
    if not _is_learned(calibration):
        return None
    powers = np.asarray(powers_w, dtype=float)
    truth = np.asarray(frequency_hz, dtype=float)
    bound = np.empty(truth.size)
    for window, rows in _window_rows(calibration, truth):
        phase = delay_phase_rad(truth[rows], window.center_hz_, window.delay_s_)
        bound[rows] = window.frequency_std_hz(powers[rows], phase_rad=phase)
    return bound


def _unit_power_samples(calibrator: BaseCalibrator, powers: np.ndarray) -> np.ndarray:
    """Retrieved object samples ``r [cos t, sin t]``, ``r = |x_12| sqrt 2 / x_3`` (N, 2)."""
    objects = powers @ linalg.pinv(calibrator.map_).T
    radius = np.hypot(objects[:, 0], objects[:, 1]) * SQRT2 / objects[:, 2]
    phase = calibrator.phase(powers)
    return radius[:, None] * np.column_stack([np.cos(phase), np.sin(phase)])


def _central(calibration: BaseCalibrator) -> BaseCalibrator:
    """The calibration itself, or the middle window of a set."""
    if isinstance(calibration, CalibrationSet):
        return calibration.windows_[len(calibration.windows_) // 2]
    return calibration


def _central_rows(calibration: BaseCalibrator, frequency_hz: np.ndarray) -> np.ndarray:
    """Readings shown in the single-FSR figures: the middle window, or near the centre."""
    if isinstance(calibration, CalibrationSet):
        return calibration.window_index(frequency_hz) == len(calibration.windows_) // 2
    half_width = FRINGE_HALF_WIDTH_FSR * calibration.fsr_hz_
    return np.abs(frequency_hz - calibration.center_hz_) <= half_width


def _fringe_figure(calibration, learned_name: str, learned, sweep: _Readings):
    """Sweep readings and the learned fringes over the centre stretch (a set: middle window)."""
    from .figures import plot_fringes

    rows = _central_rows(calibration, sweep.frequency_hz)
    model = _central(learned)
    model_hz = np.linspace(
        sweep.frequency_hz[rows].min(), sweep.frequency_hz[rows].max(), MODEL_POINTS
    )
    phase = delay_phase_rad(model_hz, model.center_hz_, model.delay_s_)
    return plot_fringes(
        sweep.frequency_hz[rows],
        sweep.powers_w[rows],
        calibration.center_hz_,
        calibration.port_names_,
        model_hz,
        cone_vectors(phase) @ model.map_.T,
        model_label=learned_name,
    )


def _object_space_figure(calibration, methods: dict, evaluation: _Readings):
    """Retrieved object samples of each method with a map, centre stretch (a set: middle)."""
    from .figures import plot_object_space

    rows = _central_rows(calibration, evaluation.frequency_hz)
    powers = evaluation.powers_w[rows]
    frame = _central(calibration)
    samples = {
        name: _unit_power_samples(_central(cal), powers)
        for name, cal in methods.items()
        if hasattr(_central(cal), "map_")
    }
    offset = evaluation.frequency_hz[rows] - frame.center_hz_
    return plot_object_space(wrap_phase_rad(2 * np.pi * offset / frame.fsr_hz_), samples)


def report_content(
    calibration: BaseCalibrator, sweep, test=None, port_phases_rad=None
) -> tuple[dict, dict]:
    """The report's figures and numbers, without writing anything.

    Parameters
    ----------
    calibration, sweep, test, port_phases_rad
        As for :func:`write_report`.

    Returns
    -------
    figures : dict of str to matplotlib.figure.Figure
        Keys ``fringes``, ``object_space``, ``retrieved``, ``residual``, ``histogram``.
    summary : dict
        JSON-ready numbers shown in the page: ``methods`` (error summaries, Hz),
        ``crlb_rms_hz``, ``evaluated_on``, ``samples``, and ``adjacent`` for sets.
    """
    from . import figures as plotting

    check_fitted(calibration)
    ports = calibration.n_ports_
    calibration_readings = _readings(sweep, "sweep", ports)
    evaluation = calibration_readings if test is None else _readings(test, "test", ports)
    if isinstance(calibration, CalibrationSet):
        _check_inside(calibration, evaluation.frequency_hz, "sweep" if test is None else "test")
    other = comparison_calibration(
        calibration,
        calibration_readings.powers_w,
        calibration_readings.frequency_hz,
        calibration_readings.monitor_w,
        port_phases_rad,
    )
    methods = {_label(calibration): calibration, _label(other): other}
    learned_name = next(name for name, cal in methods.items() if _is_learned(cal))
    learned = methods[learned_name]
    truth, powers = evaluation.frequency_hz, evaluation.powers_w
    retrieved = {name: retrieved_frequency_hz(cal, powers, truth) for name, cal in methods.items()}
    errors = {name: values - truth for name, values in retrieved.items()}
    bound = crlb_per_reading_hz(learned, powers, truth)
    crlb_rms = float(np.sqrt(np.mean(bound**2)))
    center = calibration.center_hz_

    edges = calibration.window_edges_hz_ if isinstance(calibration, CalibrationSet) else None
    figures = {
        "fringes": _fringe_figure(calibration, learned_name, learned, calibration_readings),
        "object_space": _object_space_figure(calibration, methods, evaluation),
        "retrieved": plotting.plot_retrieved_frequency(truth, retrieved, center),
        "residual": plotting.plot_residuals(
            truth, errors, center, learned_name, crlb_std_hz=bound, window_edges_hz=edges
        ),
        "histogram": plotting.plot_error_histogram(
            errors[learned_name], crlb_rms, label=learned_name
        ),
    }
    summary = {
        "evaluated_on": "calibration sweep" if test is None else "test readings",
        "samples": int(truth.size),
        "crlb_rms_hz": crlb_rms,
        "methods": {name: error_summary_hz(error) for name, error in errors.items()},
    }
    if isinstance(calibration, CalibrationSet):
        summary["adjacent"] = _adjacent_or_reason(calibration, powers, truth)
    return figures, summary


def _adjacent_or_reason(calibration: CalibrationSet, powers, truth) -> dict | str:
    try:
        return adjacent_evaluation(calibration, powers, truth)
    except InputError as exc:  # too few windows in the evaluation readings: say why
        return str(exc)


# ---------------------------------------------------------------------------- HTML
_STYLE = """
body { font-family: sans-serif; max-width: 60em; margin: 2em auto; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; }
th, td { border: 1px solid #bbb; padding: 0.25em 0.6em; text-align: right; }
th:first-child, td:first-child { text-align: left; }
figure { margin: 1.5em 0; } img { max-width: 100%; }
figcaption { font-size: 0.9em; color: #444; }
"""


def _html_table(header: list[str], rows: list[list[str]]) -> str:
    head = "".join(f"<th>{html.escape(cell)}</th>" for cell in header)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(cell)}</td>" for cell in row) + "</tr>" for row in rows
    )
    return f"<table><tr>{head}</tr>{body}</table>"


def _mhz(value_hz: float) -> str:
    return f"{value_hz / 1e6:.4g}"


def _calibration_rows(calibration: BaseCalibrator) -> list[list[str]]:
    low, high = calibration.span_hz_
    center = calibration.center_hz_
    rows = [
        ["method", _label(calibration)],
        ["design FSR (GHz)", f"{calibration.get_params()['fsr_hz'] / 1e9:.6g}"],
        ["fitted FSR (GHz)", f"{calibration.fsr_hz_ / 1e9:.9g}"],
        ["centre (THz)", f"{center / 1e12:.9g}"],
        ["centre vacuum wavelength (nm)", f"{SPEED_OF_LIGHT_M_S / center * 1e9:.6f}"],
        ["sweep span (GHz)", f"{(high - low) / 1e9:.6g}"],
        ["ports", ", ".join(calibration.port_names_)],
        ["calibration samples", str(calibration.n_samples_)],
        ["calibration RMS error (MHz)", _mhz(calibration.calibration_rms_hz_)],
    ]
    if isinstance(calibration, CalibrationSet):
        rows.append(["windows (one FSR each)", str(len(calibration.windows_))])
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
            f"{stats['rms_hz'] / crlb:.3g}",
        ]
        for name, stats in summary["methods"].items()
    ]
    rows.append(["CRLB", _mhz(crlb), "", "", "", "1"])
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
        "<h2>Maps applied to the neighbouring FSRs (paper Fig. 9)</h2>"
        f"<p>Adjacent over own RMS: {adjacent['degradation_rms']:.3g}.</p>"
        + _html_table(header, rows)
    )


def _page(calibration, summary: dict, images: dict[str, bytes]) -> str:
    from .._version import __version__

    figures = "".join(
        f'<figure><img alt="{html.escape(name)}" src="data:image/png;base64,'
        f'{base64.b64encode(png).decode("ascii")}">'
        f"<figcaption>{html.escape(FIGURE_CAPTIONS[name])}</figcaption></figure>"
        for name, png in images.items()
    )
    adjacent = _adjacent_html(summary["adjacent"]) if "adjacent" in summary else ""
    created = datetime.now(UTC).isoformat(timespec="seconds")
    errors_header = ["method", "RMS (MHz)", "max (MHz)", "p95 (MHz)", "p99 (MHz)", "RMS / CRLB"]
    return (
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        f"<title>wavemeter calibration report</title><style>{_STYLE}</style></head><body>"
        "<h1>wavemeter calibration report</h1>"
        + _html_table(["calibration", "value"], _calibration_rows(calibration))
        + f"<h2>Frequency error on the {html.escape(summary['evaluated_on'])} "
        f"({summary['samples']} readings)</h2>"
        + _html_table(errors_header, _error_rows(summary))
        + adjacent
        + figures
        + f"<p><small>wavemeter {html.escape(__version__)}, {created}</small></p>"
        "</body></html>\n"
    )


def write_report(
    calibration: BaseCalibrator,
    sweep,
    test=None,
    out_html="report.html",
    *,
    port_phases_rad=None,
    dpi: int = DEFAULT_DPI,
) -> list[Path]:
    """Write an HTML report of a calibration with its figures, and the figures as PNG files.

    Parameters
    ----------
    calibration : BaseCalibrator
        A fitted calibration (learned, conventional or a :class:`CalibrationSet`).
    sweep : object
        The calibration sweep: any object with ``powers_w`` (N, n) in W and ``frequency_hz``
        or ``x_hz`` (N,) in Hz; ``monitor_w`` (N,) is used when present.
    test : object, optional
        Test readings with known frequencies, same attributes. Default: evaluate on the
        sweep.
    out_html : str or Path
        The HTML file; PNGs are written beside it as ``<stem>-<figure>.png``.
    port_phases_rad : None or array_like, shape (n,)
        Nominal port phases of the design for the conventional comparison (rad).
    dpi : int
        Resolution of the PNG figures.

    Returns
    -------
    list of Path
        The HTML file, then the PNG files.

    Raises
    ------
    ValueError, TypeError
        When the tables do not fit the calibration (ports, missing frequencies, bad values)
        or the output folder does not exist.
    """
    figures, summary = report_content(calibration, sweep, test, port_phases_rad)
    images = {}
    for name, figure in figures.items():
        buffer = io.BytesIO()
        figure.savefig(buffer, format="png", dpi=dpi)
        images[name] = buffer.getvalue()
    target = Path(out_html)
    written = [target]
    for name, png in images.items():
        path = target.with_name(f"{target.stem}-{name}.png")
        with atomic_path(path) as temporary:
            temporary.write_bytes(png)
        written.append(path)
    with atomic_path(target) as temporary:
        temporary.write_text(_page(calibration, summary, images), encoding="utf-8")
    return written

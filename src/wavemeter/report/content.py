"""What the report shows, computed: the comparison method, errors, bounds, figures.

The calibration is compared with the method it names (``comparison()``), fitted on the
same sweep, and evaluated on the test readings (or on the sweep when there are none).
Everything specific to a method comes from what the calibration declares: its parts, its
fringes and object samples (``fringe_panels``, ``object_samples``), its own figures
(``report_figures``) and checks (``evaluation_checks``), and whether it needs the chip
temperature (``requires``), which adds the error against temperature. The bound and the
noise are those of the first method with a Cramer-Rao bound (``"crlb"``). Readings the
calibration cannot read get no error and are counted by flag. Nothing here writes a file.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..analysis.evaluation import crlb_per_reading_hz, evaluate_calibrations
from ..calibration.contract.base import BaseCalibrator
from ..exceptions import InputError, recorded_calibration_warnings
from ..model.errors import frequency_error_hz
from ..validation import check_fitted, check_frequency, check_per_reading, check_powers

__all__ = [
    "report_content",
    "comparison_calibration",
    "retrieved_frequency_hz",
]


@dataclass(frozen=True)
class _Readings:
    frequency_hz: np.ndarray
    powers_w: np.ndarray
    monitor_w: np.ndarray | None
    temperature_k: np.ndarray | None = None


def _needs_temperature(calibration: BaseCalibrator) -> bool:
    return "temperature_k" in calibration.requires


def _readings(table, role: str, ports: int, temperature: bool = False) -> _Readings:
    """Validated arrays of a table (an :class:`~wavemeter.io.table.Table` or any object
    with these attributes): ``powers_w`` (N, n) and ``frequency_hz`` or ``x_hz`` (N,),
    optionally ``monitor_w``; with ``temperature`` also ``temperature_k`` (N,), K."""
    frequency = getattr(table, "frequency_hz", None)
    if frequency is None:
        frequency = getattr(table, "x_hz", None)
    if frequency is None or not hasattr(table, "powers_w"):
        raise InputError(
            f"{role} must have attributes powers_w (N, n) and frequency_hz or x_hz (N,), "
            f"got {type(table).__name__} without them",
            parameter=role,
        )
    try:
        powers = check_powers(table.powers_w, min_samples=1, ports=ports)
        frequency = check_frequency(frequency, powers.shape[0], name=f"{role} frequency")
    except InputError as exc:
        raise InputError(f"{role}: {exc}", parameter=role) from exc
    temperature_k = getattr(table, "temperature_k", None)
    monitor = getattr(table, "monitor_w", None)
    if temperature:
        if temperature_k is None:
            raise InputError(
                f"{role}: the calibration needs the chip temperature of each reading; give a "
                "table with temperature_k (N,), K (a file with a temperature column)",
                parameter=role,
            )
        try:
            temperature_k = check_per_reading("temperature_k", temperature_k, powers.shape[0])
        except InputError as exc:
            raise InputError(f"{role}: {exc}", parameter=role) from exc
    monitor = None if monitor is None else np.asarray(monitor, float)
    return _Readings(frequency, powers, monitor, temperature_k if temperature else None)


def comparison_calibration(
    calibration: BaseCalibrator,
    powers_w,
    frequency_hz,
    power_monitor_w=None,
    port_phases_rad=None,
) -> BaseCalibrator:
    """The method ``calibration`` names for comparison, fitted on the same sweep.

    Parameters
    ----------
    calibration : BaseCalibrator
        The fitted calibration under report.
    powers_w : array_like, shape (N, n)
        Calibration sweep readings (W).
    frequency_hz : array_like, shape (N,)
        Their known frequencies (Hz).
    power_monitor_w : None or array_like, shape (N,)
        Source-power monitor (W).
    port_phases_rad : None or array_like, shape (n,)
        Nominal port phases for a conventional comparison (default equally spaced).

    Returns
    -------
    BaseCalibrator

    Raises
    ------
    InputError
        When the calibration names no comparison (the message says why), or it cannot be
        fitted on this sweep.
    """
    fitted = calibration.comparison(port_phases_rad=port_phases_rad)
    return fitted.fit(powers_w, frequency_hz, power_monitor_w, calibration.port_names_)


def retrieved_frequency_hz(
    calibration: BaseCalibrator, powers_w, frequency_hz, temperature_k=None
) -> np.ndarray:
    """Frequency (Hz) each reading is retrieved at, the alias nearest its true frequency;
    NaN for a reading the calibration cannot read.

    A calibration that needs a coarse frequency (a set, a wide band) is given the true
    frequency as the coarse value; a calibration that needs the chip temperature gets
    ``temperature_k`` (K, scalar or (N,)); a calibration that reads absolute frequency (a
    cascade) returns its own, whole FSRs off where it took a wrong fringe order.
    """
    truth = np.asarray(frequency_hz, dtype=float)
    if "coarse_hz" in calibration.requires:
        return calibration.predict(powers_w, coarse_hz=truth)
    if calibration.absolute_frequency:
        return calibration.predict(powers_w)
    inputs = {"temperature_k": temperature_k} if _needs_temperature(calibration) else {}
    predicted = calibration.predict(powers_w, **inputs)
    return truth + frequency_error_hz(predicted, truth, calibration.fsr_hz_)


def _compared(calibration, sweep: _Readings, port_phases_rad):
    """The comparison fitted on the sweep (None when there is none), why there is none,
    and the warnings its fit gave (emitted again unless the method expects them)."""
    other, reason = None, None
    with recorded_calibration_warnings() as noted:
        try:
            other = comparison_calibration(
                calibration, sweep.powers_w, sweep.frequency_hz, sweep.monitor_w, port_phases_rad
            )
        except InputError as exc:  # a calibration no other method compares with: alone
            reason = str(exc)
    if not calibration.comparison_misfits_expected:
        for warning in noted:
            warnings.warn(warning, stacklevel=3)
    return other, reason, noted


def _part_edges_hz(calibration) -> np.ndarray | None:
    """The boundaries of a composite's windows (Hz), for the error figure; None else."""
    ranges = [part.range_hz for part in calibration.parts() if part.kind == "window"]
    return np.unique(np.ravel(ranges)) if ranges else None


def report_content(
    calibration: BaseCalibrator, sweep, test=None, port_phases_rad=None
) -> tuple[dict, dict]:
    """The report's figures and numbers, without writing anything.

    Parameters
    ----------
    calibration, sweep, test, port_phases_rad
        As for :func:`wavemeter.report.write_report`.

    Returns
    -------
    figures : dict of str to matplotlib.figure.Figure
        ``fringes`` (one panel pair per part), ``object_space``, ``retrieved``,
        ``residual``, ``histogram``; ``temperature`` for a calibration that needs the
        chip temperature; the calibration's own ``report_figures``.
    summary : dict
        JSON-ready numbers shown in the page: ``methods``, ``crlb_rms_hz``,
        ``noise_std_w`` and ``noise_from`` as :func:`~wavemeter.analysis.evaluate_calibrations`
        gives them for these methods and readings (the numbers ``wavemeter evaluate``
        prints; each method's ``flagged`` counts are those ``measure`` prints), ``unread``
        (per method, the readings it could not read, by flag),
        ``evaluated_on``, ``samples``, ``comparison`` (its
        label, None when there is none) and ``comparison_error`` (why not, else None),
        ``comparison_warnings`` (``[cause] message`` of each warning the comparison's fit
        gave), ``captions`` (of the calibration's own figures), ``checks`` (each check
        the calibration makes, ``evaluation_checks``, with its title, text and table) and
        each check's numbers by its name (``adjacent`` for sets, ``order_errors`` for a
        cascade).
    """
    from . import figures as plotting
    from .fringes import plot_panels

    check_fitted(calibration)
    ports = calibration.n_ports_
    thermal = _needs_temperature(calibration)
    sweep_readings = _readings(sweep, "sweep", ports, thermal)
    evaluation = sweep_readings if test is None else _readings(test, "test", ports, thermal)
    other, comparison_error, comparison_warnings = _compared(
        calibration, sweep_readings, port_phases_rad
    )
    methods = {calibration.method_label: calibration}
    if other is not None:
        methods[other.method_label] = other
    # the bound, the noise and the fringes are those of the first method with a bound
    reference_name = next(
        (name for name, cal in methods.items() if "crlb" in cal.capabilities),
        calibration.method_label,
    )
    reference = methods[reference_name]
    truth, powers = evaluation.frequency_hz, evaluation.powers_w
    retrieved = {
        name: retrieved_frequency_hz(cal, powers, truth, evaluation.temperature_k)
        for name, cal in methods.items()
    }
    read = np.all([np.isfinite(values) for values in retrieved.values()], axis=0)
    if not read.any():
        raise InputError(
            f"{'sweep' if test is None else 'test'}: the calibration cannot read any of the "
            f"{truth.size} readings (outside the range it has maps for): give readings "
            "inside the calibrated band",
            parameter="sweep" if test is None else "test",
        )
    kept = _Readings(
        truth[read],
        powers[read],
        None,
        None if evaluation.temperature_k is None else evaluation.temperature_k[read],
    )
    retrieved = {name: values[read] for name, values in retrieved.items()}
    errors = {name: values - kept.frequency_hz for name, values in retrieved.items()}
    bound = crlb_per_reading_hz(reference, kept.powers_w, kept.frequency_hz, kept.temperature_k)
    crlb_rms = None if bound is None else float(np.sqrt(np.nanmean(bound**2)))
    center = calibration.center_hz_
    samples = {}
    for name, cal in methods.items():
        found = cal.object_samples(kept.powers_w, kept.frequency_hz, kept.temperature_k)
        if found is not None:
            samples[name] = found
    panels = reference.fringe_panels(
        sweep_readings.frequency_hz,
        sweep_readings.powers_w,
        sweep_readings.monitor_w,
        sweep_readings.temperature_k,
    )
    figures = {}
    if panels:  # a method with no model of the fringes draws none
        figures["fringes"] = plot_panels(panels, reference.port_names_, model_label=reference_name)
    figures |= {
        "object_space": plotting.plot_object_space(samples),
        "retrieved": plotting.plot_retrieved_frequency(kept.frequency_hz, retrieved, center),
        "residual": plotting.plot_residuals(
            kept.frequency_hz,
            errors,
            center,
            reference_name,
            crlb_std_hz=bound,
            window_edges_hz=_part_edges_hz(calibration),
        ),
        "histogram": plotting.plot_error_histogram(
            errors[reference_name], crlb_rms, label=reference_name
        ),
    }
    if thermal:
        figures["temperature"] = plotting.plot_error_against_temperature(
            kept.temperature_k,
            errors,
            calibration.method_label,
            (calibration.diagnostics_ or {}).get("temperature_range_k"),
            crlb_std_hz=bound,
        )
    captions = {}
    for data in calibration.report_figures(crlb_rms):
        figures[data.name] = plotting.plot_figure_data(data)
        captions[data.name] = data.caption
    numbers = evaluate_calibrations(methods, powers, truth, temperature_k=evaluation.temperature_k)
    summary = {
        "evaluated_on": "calibration sweep" if test is None else "test readings",
        "samples": int(truth.size),
        "unread": {
            name: figures["unread"]
            for name, figures in numbers["methods"].items()
            if figures["unread"]
        },
        "crlb_rms_hz": numbers["crlb_rms_hz"],
        "noise_std_w": numbers["noise_std_w"],
        "noise_from": numbers["crlb_method"],
        "methods": numbers["methods"],
        "comparison": None if other is None else other.method_label,
        "comparison_error": comparison_error,
        "comparison_warnings": [f"[{warning.cause}] {warning}" for warning in comparison_warnings],
        "checks": [],
        "captions": captions,
    }
    for check in calibration.evaluation_checks(kept.powers_w, kept.frequency_hz):
        summary[check.name] = check.record
        summary["checks"].append(
            {
                "name": check.name,
                "title": check.title,
                "text": check.text,
                "table": None if check.table is None else check.table.as_dict(),
            }
        )
    return figures, summary

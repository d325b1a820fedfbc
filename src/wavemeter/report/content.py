"""What the report shows, computed: the comparison method, errors, bounds, figures.

The calibration is compared with the other method (learned against conventional) fitted
on the same sweep, and evaluated on the test readings (or on the sweep when there are
none): fringes, fitted model and residuals (paper Fig. 4b / 7a; every window of a set),
object space (Fig. 4a), retrieved frequency and error (Figs. 4c,d / 7b,c), error histogram
against the Cramer-Rao bound, and for calibration sets the error across the whole span
(Fig. 8) and the adjacent-window evaluation (Fig. 9). Nothing here writes a file.

The comparison's calibration warnings are listed in the page and emitted again. A
calibration that needs the chip temperature (``"temperature_k"`` in its ``requires``: a
thermal one) takes it from the tables' ``temperature_k``; it is compared with the plain
learned calibration fitted on the same sweep without the temperature, whose warnings (a
phase drift, expected for a sweep over several temperatures) are listed in the page only,
and the report adds the frequency error against the chip temperature. Its fringes are
drawn at the frequency that has the same model phase at the reference temperature, so that
readings at every temperature lie on one fringe.

A wide-band calibration (:class:`~wavemeter.calibration.methods.wideband.WidebandCalibrator`) is
compared with the learned calibration set fitted per FSR on the same sweep (the other way
to cover a band), reads every reading with the truth as its coarse frequency, and adds the
cross-validation curve of its orders and the residual phase across the band, per FSR
window (``diagnostics_["wideband"]``).

A cascade calibration (:class:`~wavemeter.calibration.methods.cascade.CascadeCalibrator`) is shown
alone: no other method reads absolute frequency from the same readings. Its errors are
absolute (a wrong fringe order shows as a whole FSR), its fringes and object space are
those of its finest stage (the stage the answer comes from), its Cramer-Rao bound and noise
those of the finest stage, and the summary counts the wrong fringe orders of the evaluation
readings against those its ``order_error_probability`` predicts and those it flags.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import linalg

from ..analysis.evaluation import adjacent_evaluation, crlb_per_reading_hz
from ..analysis.metrics import error_summary_hz, frequency_error_hz
from ..calibration.contract.base import BaseCalibrator
from ..calibration.contract.flags import ReadingFlag
from ..calibration.methods.baselines import ConventionalCalibrator
from ..calibration.methods.cascade import CascadeCalibrator
from ..calibration.methods.learned import Calibrator
from ..calibration.methods.set import CalibrationSet
from ..calibration.methods.wideband import WidebandCalibrator
from ..calibration.models.wideband_fit import BandModel
from ..exceptions import InputError, recorded_calibration_warnings
from ..model.cone import SQRT2, cone_vectors, delay_phase_rad
from ..validation import check_fitted, check_frequency, check_per_reading, check_powers
from .fringes import FringePanel
from .page import wideband_record

__all__ = [
    "report_content",
    "comparison_calibration",
    "order_errors",
    "retrieved_frequency_hz",
    "learned_noise_std_w",
]

MODEL_POINTS = 1000


#: half width, in FSRs, of the stretch of a single calibration's sweep shown as fringes
FRINGE_HALF_WIDTH_FSR = 1.5


@dataclass(frozen=True)
class _Readings:
    frequency_hz: np.ndarray
    powers_w: np.ndarray
    monitor_w: np.ndarray | None
    temperature_k: np.ndarray | None = None


def _needs_temperature(calibration: BaseCalibrator) -> bool:
    return "temperature_k" in calibration.requires


def _temperature_inputs(calibration: BaseCalibrator, temperature_k) -> dict:
    """``{"temperature_k": ...}`` for a calibration that needs it, else nothing."""
    return {"temperature_k": temperature_k} if _needs_temperature(calibration) else {}


def _readings(table, role: str, ports: int, temperature: bool = False) -> _Readings:
    """Validated arrays of a table: ``frequency_hz`` or ``x_hz`` (N,), ``powers_w`` (N, n);
    with ``temperature`` also ``temperature_k`` (N,), K, which must be there."""
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
    monitor = getattr(table, "monitor_w", None)
    temperature_k = getattr(table, "temperature_k", None)
    if temperature and temperature_k is None:
        raise InputError(
            f"{role}: the calibration needs the chip temperature of each reading; give a "
            "table with temperature_k (N,), K (a file with a temperature column)",
            parameter=role,
        )
    if temperature:
        try:
            temperature_k = check_per_reading("temperature_k", temperature_k, powers.shape[0])
        except InputError as exc:
            raise InputError(f"{role}: {exc}", parameter=role) from exc
    return _Readings(
        frequency,
        powers,
        None if monitor is None else np.asarray(monitor, float),
        temperature_k if temperature else None,
    )


def _check_inside(calibration: BaseCalibrator, frequency_hz: np.ndarray, role: str) -> None:
    """Every reading inside the range a set has windows for, or a wide band was calibrated
    on (it would be read with no map, or beside the per-FSR comparison's)."""
    low, high = _calibrated_range_hz(calibration)
    outside = (frequency_hz < low) | (frequency_hz > high)
    if outside.any():
        what = "calibration set" if isinstance(calibration, CalibrationSet) else "calibrated band"
        raise InputError(
            f"{role}: {int(outside.sum())} readings lie outside the {what}'s span "
            f"{low / 1e12:.6f} to {high / 1e12:.6f} THz (first at "
            f"{frequency_hz[outside][0] / 1e12:.6f} THz); a {calibration.method_label} "
            "calibration is evaluated only where it has a map: drop them",
            parameter=role,
        )


def _windows(calibration: BaseCalibrator) -> list[BaseCalibrator]:
    """The single-FSR calibrators of a set, or the calibration itself."""
    if isinstance(calibration, CalibrationSet):
        return list(calibration.windows_)
    return [calibration]


def _central(calibration: BaseCalibrator) -> BaseCalibrator:
    """The calibration itself, or the middle window of a set."""
    windows = _windows(calibration)
    return windows[len(windows) // 2]


def _is_learned(calibration: BaseCalibrator) -> bool:
    return isinstance(_central(calibration), (Calibrator, WidebandCalibrator))


def _is_wideband(calibration: BaseCalibrator) -> bool:
    return isinstance(calibration, WidebandCalibrator)


def _is_cascade(calibration: BaseCalibrator) -> bool:
    return isinstance(calibration, CascadeCalibrator)


def _finest_stage(calibration: CascadeCalibrator, readings: _Readings):
    """The finest stage of a cascade, the readings of its columns alone and its port names."""
    columns = list(calibration.stage_ports_[-1])
    stage_readings = _Readings(
        readings.frequency_hz, readings.powers_w[:, columns], readings.monitor_w
    )
    names = [calibration.port_names_[column] for column in columns]
    return calibration.stages_[-1], stage_readings, names


def _band_model(calibration: WidebandCalibrator) -> BandModel:
    """The fitted phase polynomial and map of a wide-band calibration."""
    return BandModel(
        calibration.center_hz_,
        calibration.half_span_hz_,
        calibration.phase_coefficients_rad_,
        calibration.map_coefficients_,
    )


def _calibrated_range_hz(calibration: BaseCalibrator) -> tuple[float, float]:
    """The frequencies (Hz) a set has windows for, or a wide band was calibrated on."""
    if isinstance(calibration, CalibrationSet):
        return calibration.covered_hz()
    low, high = calibration.span_hz_
    return float(low), float(high)


def learned_noise_std_w(calibration: BaseCalibrator) -> float | None:
    """Detector noise estimate (W) of a learned calibration: its ``noise_std_w_``, the mean
    over the windows of a set, a cascade's finest stage's; None for other methods."""
    if _is_cascade(calibration):
        return float(calibration.stages_[-1].noise_std_w_)
    if not _is_learned(calibration):
        return None
    return float(np.mean([window.noise_std_w_ for window in _windows(calibration)]))


def comparison_calibration(
    calibration: BaseCalibrator,
    powers_w,
    frequency_hz,
    power_monitor_w=None,
    port_phases_rad=None,
) -> BaseCalibrator:
    """The other method fitted on the same sweep: learned for any other, else conventional;
    for a wide band, the learned calibration set per FSR.

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
        Fitted with the design FSR of ``calibration``; for a calibration that needs the
        chip temperature, the plain learned calibration with its FSR settings and
        retrieval, fitted without the temperature (what the temperature buys); for a
        wide-band calibration, a set of learned calibrations, one per FSR, with its FSR
        settings and retrieval (what one model of the band buys).

    Raises
    ------
    InputError
        For a cascade calibration: no other method reads absolute frequency from its
        readings.
    """
    if _is_cascade(calibration):
        raise InputError(
            "a cascade calibration has no other method to fit on its sweep for comparison: "
            "no other method reads absolute frequency from the readings of its stages; "
            "evaluate it alone, or beside another calibration file",
            parameter="comparison",
        )
    design = calibration.fsr_hz
    own = _central(calibration)
    phases = own.get_params().get("port_phases_rad") if port_phases_rad is None else port_phases_rad
    if _needs_temperature(calibration) or _is_wideband(calibration):
        settings = calibration.get_params()
        fitted = Calibrator(
            fsr_hz=design,
            fsr_tolerance=settings["fsr_tolerance"],
            retrieval=settings["retrieval"],
        )
        if _is_wideband(calibration):
            fitted = CalibrationSet(design, settings["fsr_tolerance"], window=fitted)
    elif _is_learned(calibration):
        fitted = ConventionalCalibrator(fsr_hz=design, port_phases_rad=phases)
    else:
        fitted = Calibrator(fsr_hz=design)
    if isinstance(calibration, CalibrationSet):
        fitted = CalibrationSet(design, calibration.fsr_tolerance, window=fitted)
    return fitted.fit(powers_w, frequency_hz, power_monitor_w, calibration.port_names_)


def retrieved_frequency_hz(
    calibration: BaseCalibrator, powers_w, frequency_hz, temperature_k=None
) -> np.ndarray:
    """Frequency (Hz) each reading is retrieved at, the alias nearest its true frequency.

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
    predicted = calibration.predict(powers_w, **_temperature_inputs(calibration, temperature_k))
    return truth + frequency_error_hz(predicted, truth, calibration.fsr_hz_)


def _model_phase_rad(model: Calibrator, frequency_hz, temperature_k=None) -> np.ndarray:
    """The phase a learned model gives readings of frequency ``frequency_hz`` (Hz): at their
    chip temperature ``temperature_k`` (K) for a model that needs it."""
    if not _needs_temperature(model):
        return delay_phase_rad(frequency_hz, model.center_hz_, model.delay_s_)
    from ..calibration.models.thermal_fit import thermal_phase_rad

    return thermal_phase_rad(
        frequency_hz,
        temperature_k,
        model.center_hz_,
        model.reference_temperature_k_,
        model.delay_s_,
        model.thermal_phase_rad_per_k_,
        model.thermal_delay_per_k_,
    )


def _crlb_hz(learned: BaseCalibrator, readings: _Readings) -> np.ndarray:
    """Per-reading Cramer-Rao standard deviation (Hz) at the true frequency, under the
    learned calibration's own model (:func:`crlb_per_reading_hz`)."""
    return crlb_per_reading_hz(
        learned, readings.powers_w, readings.frequency_hz, readings.temperature_k
    )


def _window_rows(calibration: BaseCalibrator, frequency_hz: np.ndarray):
    """(single calibrator, rows) pairs covering the readings: each window of a set, or all."""
    if not isinstance(calibration, CalibrationSet):
        return [(calibration, np.ones(frequency_hz.size, dtype=bool))]
    index = calibration.window_index(frequency_hz)
    return [(calibration.windows_[k], index == k) for k in np.unique(index)]


# ---------------------------------------------------------------------------- figure data
def _fringe_panel(model: Calibrator, sweep: _Readings, rows: np.ndarray, title: str = ""):
    """Readings of ``rows``, the learned model's fringes and its fit at each reading.

    A model that needs the chip temperature places each reading at the frequency whose
    phase at the reference temperature is the reading's model phase, so that the
    readings of every temperature lie on the fringes drawn (those at the reference)."""
    frequency, powers = sweep.frequency_hz[rows], sweep.powers_w[rows]
    temperature = None if sweep.temperature_k is None else sweep.temperature_k[rows]
    phase = _model_phase_rad(model, frequency, temperature)
    if _needs_temperature(model):
        frequency = model.center_hz_ + phase / (2.0 * np.pi * model.delay_s_)
    fitted = cone_vectors(phase) @ model.map_.T
    if sweep.monitor_w is not None:  # the map is per unit of the mean monitor reading
        monitor = sweep.monitor_w[rows]
        fitted = fitted * (monitor / monitor.mean())[:, None]
    model_hz = np.linspace(frequency.min(), frequency.max(), MODEL_POINTS)
    curve = cone_vectors(delay_phase_rad(model_hz, model.center_hz_, model.delay_s_))
    return FringePanel(
        center_hz=model.center_hz_,
        frequency_hz=frequency,
        powers_w=powers,
        fitted_w=fitted,
        model_frequency_hz=model_hz,
        model_powers_w=curve @ model.map_.T,
        noise_std_w=model.noise_std_w_,
        title=title,
    )


def _band_fringe_panel(calibration: WidebandCalibrator, sweep: _Readings, rows: np.ndarray):
    """Readings of ``rows``, the wide-band model's fringes (its phase polynomial and its
    map at each frequency) and its fit at each reading."""
    model = _band_model(calibration)
    frequency, powers = sweep.frequency_hz[rows], sweep.powers_w[rows]

    def model_powers_w(frequency_hz):
        vectors = cone_vectors(model.phase_rad(frequency_hz))
        return np.einsum("knc,kc->kn", model.maps_at(frequency_hz), vectors)

    fitted = model_powers_w(frequency)
    if sweep.monitor_w is not None:  # the map is per unit of the mean monitor reading
        monitor = sweep.monitor_w[rows]
        fitted = fitted * (monitor / monitor.mean())[:, None]
    model_hz = np.linspace(frequency.min(), frequency.max(), MODEL_POINTS)
    return FringePanel(
        center_hz=calibration.center_hz_,
        frequency_hz=frequency,
        powers_w=powers,
        fitted_w=fitted,
        model_frequency_hz=model_hz,
        model_powers_w=model_powers_w(model_hz),
        noise_std_w=calibration.noise_std_w_,
        title=f"readings within {FRINGE_HALF_WIDTH_FSR:g} FSR of the one nearest the middle "
        "of the band",
    )


def _fringe_figure(learned: BaseCalibrator, learned_name: str, sweep: _Readings, ports):
    """A single calibration: the sweep near its centre (a wide band: near the middle of the
    band; a cascade: its finest stage there); a set: every window (small multiples)."""
    from .fringes import plot_fringes, plot_window_fringes

    if _is_cascade(learned):
        stage, stage_sweep, names = _finest_stage(learned, sweep)
        return _fringe_figure(
            stage, f"{learned_name}, stage {len(learned.stages_)}", stage_sweep, names
        )
    if isinstance(learned, CalibrationSet):
        index = learned.window_index(sweep.frequency_hz)
        panels = [
            _fringe_panel(
                window, sweep, index == k, f"window {k}: {window.center_hz_ / 1e12:.4f} THz"
            )
            for k, window in enumerate(learned.windows_)
            if np.count_nonzero(index == k) > 0
        ]
        return plot_window_fringes(panels, ports, model_label=learned_name)
    anchor = learned.center_hz_
    if _is_wideband(learned):  # the sweep may have a gap in the middle of the band
        anchor = sweep.frequency_hz[np.argmin(np.abs(sweep.frequency_hz - anchor))]
    near = np.abs(sweep.frequency_hz - anchor) <= FRINGE_HALF_WIDTH_FSR * learned.fsr_hz_
    if _is_wideband(learned):
        panel = _band_fringe_panel(learned, sweep, near)
        return plot_fringes(panel, ports, model_label=learned_name)
    title = ""
    if _needs_temperature(learned):
        title = (
            "readings at the frequency with their model phase at the reference temperature "
            f"{learned.reference_temperature_k_:.6g} K"
        )
    return plot_fringes(_fringe_panel(learned, sweep, near, title), ports, model_label=learned_name)


def _unit_power_samples(
    calibrator: BaseCalibrator, powers: np.ndarray, temperature_k=None
) -> np.ndarray:
    """Retrieved object samples ``r [cos t, sin t]``, ``r = |x_12| sqrt 2 / x_3`` (N, 2)."""
    objects = powers @ linalg.pinv(calibrator.map_).T
    radius = np.hypot(objects[:, 0], objects[:, 1]) * SQRT2 / objects[:, 2]
    phase = calibrator.phase(powers, **_temperature_inputs(calibrator, temperature_k))
    return radius[:, None] * np.column_stack([np.cos(phase), np.sin(phase)])


def _band_unit_power_samples(calibration: WidebandCalibrator, powers, truth_hz) -> np.ndarray:
    """Retrieved object samples ``r [cos t, sin t]`` (N, 2) of a wide band, each reading
    under the map at the frequency it is read at (the truth as its coarse frequency)."""
    frequency = calibration.predict(powers, coarse_hz=truth_hz)
    inverses = np.linalg.pinv(_band_model(calibration).maps_at(frequency))
    objects = np.einsum("kcn,kn->kc", inverses, powers)
    radius = np.hypot(objects[:, 0], objects[:, 1]) * SQRT2 / objects[:, 2]
    phase = calibration.phase(powers, coarse_hz=truth_hz)
    return radius[:, None] * np.column_stack([np.cos(phase), np.sin(phase)])


def _object_samples(calibration: BaseCalibrator, evaluation: _Readings) -> np.ndarray:
    """Unit-power object samples of the evaluation readings, each under its own window (a
    wide band: its own map); a single-FSR calibration: the readings within its central
    stretch."""
    truth, powers = evaluation.frequency_hz, evaluation.powers_w
    if _is_cascade(calibration):
        stage, stage_readings, _ = _finest_stage(calibration, evaluation)
        return _band_unit_power_samples(stage, stage_readings.powers_w, truth)
    if _is_wideband(calibration):
        return _band_unit_power_samples(calibration, powers, truth)
    if not isinstance(calibration, CalibrationSet):
        near = np.abs(truth - calibration.center_hz_) <= (
            FRINGE_HALF_WIDTH_FSR * calibration.fsr_hz_
        )
        temperature = None if evaluation.temperature_k is None else evaluation.temperature_k[near]
        return _unit_power_samples(calibration, powers[near], temperature)
    parts = [
        _unit_power_samples(window, powers[rows])
        for window, rows in _window_rows(calibration, truth)
    ]
    return np.concatenate(parts)


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
        Keys ``fringes`` (a set: one panel pair per window), ``object_space``,
        ``retrieved``, ``residual``, ``histogram``, ``temperature`` for a calibration
        that needs the chip temperature, ``cross_validation`` and ``residual_phase`` for a
        wide-band calibration.
    summary : dict
        JSON-ready numbers shown in the page: ``methods`` (error summaries, Hz),
        ``crlb_rms_hz``, ``noise_std_w`` and ``noise_from`` (the learned method whose
        residual gave it), ``evaluated_on``, ``samples``, ``comparison`` (its label, None
        when it could not be fitted) and ``comparison_error`` (why not, else None),
        ``comparison_warnings`` (the ``[cause] message`` of each calibration warning the
        comparison's fit gave), ``adjacent`` for sets and ``order_errors`` for a cascade
        (:func:`order_errors`).
    """
    from . import figures as plotting

    check_fitted(calibration)
    ports = calibration.n_ports_
    thermal = _needs_temperature(calibration)
    calibration_readings = _readings(sweep, "sweep", ports, thermal)
    evaluation = calibration_readings if test is None else _readings(test, "test", ports, thermal)
    if (
        isinstance(calibration, CalibrationSet)
        or _is_wideband(calibration)
        or _is_cascade(calibration)
    ):
        _check_inside(calibration, evaluation.frequency_hz, "sweep" if test is None else "test")
    other, comparison_error = None, None
    with recorded_calibration_warnings() as comparison_warnings:
        # a cascade is shown alone (comparison_calibration says why)
        try:
            if not _is_cascade(calibration):
                other = comparison_calibration(
                    calibration,
                    calibration_readings.powers_w,
                    calibration_readings.frequency_hz,
                    calibration_readings.monitor_w,
                    port_phases_rad,
                )
        except InputError as exc:
            # a learned calibration is reported on its own when the other method cannot
            # be fitted on its sweep (a plain one on sweeps at several temperatures)
            if not _is_learned(calibration):
                raise
            comparison_error = str(exc)
    # page only where the comparison is expected to misfit: a plain calibration of a thermal
    # sweep, a per-FSR set whose whole-sweep fit sees the band's dispersion
    if not (thermal or _is_wideband(calibration)):
        for warning in comparison_warnings:
            warnings.warn(warning, stacklevel=2)
    methods = {calibration.method_label: calibration}
    if other is not None:
        methods[other.method_label] = other
    learned_name = next(
        name for name, cal in methods.items() if _is_learned(cal) or _is_cascade(cal)
    )
    learned = methods[learned_name]
    truth, powers = evaluation.frequency_hz, evaluation.powers_w
    retrieved = {
        name: retrieved_frequency_hz(cal, powers, truth, evaluation.temperature_k)
        for name, cal in methods.items()
    }
    errors = {name: values - truth for name, values in retrieved.items()}
    bound = _crlb_hz(learned, evaluation)
    crlb_rms = float(np.sqrt(np.mean(bound**2)))
    center = calibration.center_hz_
    samples = {
        name: _object_samples(cal, evaluation)
        for name, cal in methods.items()
        if hasattr(_central(cal), "map_") or _is_wideband(cal) or _is_cascade(cal)
    }
    edges = calibration.window_edges_hz_ if isinstance(calibration, CalibrationSet) else None
    figures = {
        "fringes": _fringe_figure(
            learned, learned_name, calibration_readings, calibration.port_names_
        ),
        "object_space": plotting.plot_object_space(samples),
        "retrieved": plotting.plot_retrieved_frequency(truth, retrieved, center),
        "residual": plotting.plot_residuals(
            truth, errors, center, learned_name, crlb_std_hz=bound, window_edges_hz=edges
        ),
        "histogram": plotting.plot_error_histogram(
            errors[learned_name], crlb_rms, label=learned_name
        ),
    }
    if wideband_record(calibration) is not None:
        figures.update(_wideband_figures(calibration, crlb_rms))
    if thermal:
        figures["temperature"] = plotting.plot_error_against_temperature(
            evaluation.temperature_k,
            errors,
            calibration.method_label,
            calibration.temperature_range_k_,
            crlb_std_hz=bound,
        )
    summary = {
        "evaluated_on": "calibration sweep" if test is None else "test readings",
        "samples": int(truth.size),
        "crlb_rms_hz": crlb_rms,
        "noise_std_w": learned_noise_std_w(learned),
        "noise_from": learned_name,
        "methods": {name: error_summary_hz(error) for name, error in errors.items()},
        "comparison": None if other is None else other.method_label,
        "comparison_error": comparison_error,
        "comparison_warnings": [
            f"[{getattr(warning, 'cause', 'other_misfit')}] {warning}"
            for warning in comparison_warnings
        ],
    }
    if isinstance(calibration, CalibrationSet):
        summary["adjacent"] = _adjacent_or_reason(calibration, powers, truth)
    if _is_cascade(calibration):
        summary["order_errors"] = order_errors(calibration, powers, truth)
    return figures, summary


def order_errors(calibration: CascadeCalibrator, powers_w, frequency_hz) -> dict:
    """Wrong fringe orders of a cascade on readings of known frequency, against those its
    ``order_error_probability`` predicts and those it flags ``ORDER_AMBIGUOUS``.

    Parameters
    ----------
    calibration : CascadeCalibrator
        A fitted cascade.
    powers_w : array_like, shape (N, n)
        Readings of every stage, in the unit of the calibration sweep.
    frequency_hz : array_like, shape (N,)
        Their true frequencies (Hz).

    Returns
    -------
    dict
        JSON-ready: ``readings``, ``wrong_orders`` (readings off by half the finest
        stage's local FSR or more), ``expected_wrong_orders`` (sum of the readings'
        ``order_error_probability``), ``flagged_order_ambiguous`` and
        ``wrong_orders_flagged`` (the wrong ones among those flagged).
    """
    found = calibration.read(powers_w)
    truth = np.asarray(frequency_hz, dtype=float)
    wrong = np.abs(found.frequency_hz[-1] - truth) >= 0.5 * calibration.fsr_hz_at(truth)
    flagged = (found.flags & ReadingFlag.ORDER_AMBIGUOUS) != 0
    return {
        "readings": int(truth.size),
        "wrong_orders": int(np.count_nonzero(wrong)),
        "expected_wrong_orders": float(np.sum(found.order_error_probability)),
        "flagged_order_ambiguous": int(np.count_nonzero(flagged)),
        "wrong_orders_flagged": int(np.count_nonzero(wrong & flagged)),
    }


def _wideband_figures(calibration: WidebandCalibrator, crlb_rms_hz: float) -> dict:
    """The cross-validation curve of the orders and the residual phase per FSR window
    across the band (``diagnostics_["wideband"]``), with the Cramer-Rao phase ``+-1 sigma``
    of the evaluation readings (their RMS frequency bound over the FSR) as the noise level
    to judge the residual by."""
    from . import figures as plotting

    record = wideband_record(calibration)
    orders = record["orders"]
    candidates = orders["candidates"]
    residual = record["residual_phase"]
    return {
        "cross_validation": plotting.plot_cross_validation(
            [candidate["parameters"] for candidate in candidates],
            [candidate["cv_rms_hz"] for candidate in candidates],
            [(candidate["phase_order"], candidate["map_order"]) for candidate in candidates],
            [candidate["chosen"] for candidate in candidates],
            orders["reason"],
        ),
        "residual_phase": plotting.plot_residual_phase(
            [row["center_hz"] for row in residual],
            [row["mean_rad"] for row in residual],
            [row["rms_rad"] for row in residual],
            calibration.center_hz_,
            noise_std_rad=2.0 * np.pi * crlb_rms_hz / calibration.fsr_hz_,
        ),
    }


def _adjacent_or_reason(calibration: CalibrationSet, powers, truth) -> dict | str:
    try:
        return adjacent_evaluation(calibration, powers, truth)
    except InputError as exc:  # too few windows in the evaluation readings: say why
        return str(exc)

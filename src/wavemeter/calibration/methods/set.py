"""One calibration per FSR-wide window of a sweep over many FSRs (paper Section IV, Fig. 8, 9).

A single map ``A`` is optimal for the span it was learned on; over a wide band the fringe
amplitudes and the bias drift slowly, so the paper calibrates one FSR at a time and applies
each map to readings of its own FSR. :class:`CalibrationSet` does that for a sweep over many
FSRs:

1. the global delay is fitted on the whole sweep (the most precise FSR there is, and the
   only fit that can tell the true delay from a side minimum of ``J``), and checked to
   explain the fringes;
2. the sweep is cut into contiguous windows of exactly one fitted FSR, centred on the sweep;
3. each window is calibrated on its own readings alone, refitting the delay within
   +-15 % of the global FSR: the paper's per-FSR protocol, which also follows a local FSR
   that drifts across the band (dispersion). A one-FSR window has no side minimum of ``J``
   in that bracket, and its delay costs only the ``3/N`` part of ``CRLB sqrt(1 + 3/N)``.

Retrieval needs a coarse frequency per reading (the laser set point, a coarse meter, the
previous reading), good to better than half an FSR: it picks the window, and of the
window's readings modulo the FSR it picks the alias nearest the coarse value.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from ...exceptions import CalibrationWarning, InputError, recorded_calibration_warnings, shown
from ...model.cone import wrap_to_period
from ...validation import (
    MIN_SAMPLES,
    check_frequency,
    check_monitor,
    check_positive,
    check_powers,
)
from ..contract.base import BaseCalibrator
from ..contract.params import clone
from ..contract.records import ReadingInputs
from ..contract.summary import FitValue
from ..files import fields
from ..files.document import calibrator_fields, calibrator_from_fields
from ..files.registry import calibrator_class
from ..files.state import state_array, state_float
from ..fitting.reference import ReferenceCellMixin
from .learned import Calibrator
from .set_checks import adjacent_check, adjacent_evaluation, window_label
from .set_reading import WindowReadingMixin
from .set_reanchor import reanchored_set

__all__ = ["CalibrationSet", "WINDOW_FSR_TOLERANCE"]

#: half width of each window's delay bracket about the global FSR: room for the local FSR of
#: a dispersive band (8 % at the ends of 10 FSRs with a group-delay dispersion of 1e-24 s^2)
WINDOW_FSR_TOLERANCE = 0.15


class CalibrationSet(WindowReadingMixin, ReferenceCellMixin, BaseCalibrator):
    """A calibration per FSR-wide window of a sweep spanning many FSRs.

    Parameters
    ----------
    fsr_hz : float
        Design free spectral range (Hz); the global delay search brackets it.
    fsr_tolerance : float
        Relative half width of the global FSR bracket, in (0, 1). Default 0.2.
    window : None or calibrator
        An unfitted single-FSR calibrator whose settings every window copies (its FSR set
        to the global one and, where it has one, its bracket to +-15 %). Default:
        ``Calibrator()``; e.g. ``Calibrator(retrieval="ml")`` or
        ``ConventionalCalibrator(port_phases_rad=...)``.

    Attributes
    ----------
    windows_ : list of BaseCalibrator
        One fitted calibrator per window, low to high frequency; each has its own
        ``span_hz_`` (the readings it was fitted on), ``center_hz_`` and ``fsr_hz_``.
    window_edges_hz_ : ndarray, shape (K + 1,)
        Window boundaries (Hz), exactly one global FSR apart, centred on the sweep.
    delay_s_ : float
        Global delay ``tau`` (s) fitted on the whole sweep.
    delay_std_s_ : float or None
        Its standard error (s); None when loaded from a file of version 0.1.
    fsr_hz_ : float
        Global FSR ``1 / tau`` (Hz).
    center_hz_ : float
        Middle of the sweep (Hz).
    span_hz_ : (float, float)
        Lowest and highest sweep frequency (Hz).
    calibration_rms_hz_ : float
        RMS frequency error on the sweep itself, each reading given its true frequency as
        the coarse value (Hz).
    diagnostics_ : dict
        Those of the whole-sweep fit: the sweep's own FSR, port health, warnings.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(800, span_fsr=4)  # a sweep over four FSRs
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> cal_set = wm.CalibrationSet(fsr_hz=50e9).fit(powers, f_hz)
    >>> len(cal_set.windows_)  # one calibration per FSR-wide window
    4

    The global delay fit finds the device's FSR; each window then has its own map:

    >>> print(f"{cal_set.fsr_hz_ / 1e9:.2f} GHz, true {device.true_fsr_hz / 1e9:.2f} GHz")
    51.50 GHz, true 51.50 GHz

    Two test readings in different windows, each read within five of its standard
    deviations:

    >>> test_hz = f_hz[[100, 500]] + 1e8
    >>> test = device.powers(test_hz, power_w=1e-3, noise_w=5e-7, rng=2)
    >>> reading = cal_set.readout(test, coarse_hz=test_hz + 5e9)  # a coarse value picks the window
    >>> print(np.abs(reading.frequency_hz - test_hz) < 5 * reading.frequency_std_hz)
    [ True  True]
    """

    method = "calibration_set"
    requires = frozenset({"coarse_hz"})
    #: the windows' numbers are checked as each window's file (:func:`calibrator_from_fields`)
    state_rules = fields.rule_table(
        {
            "delay_s": fields.DELAY_RULE,
            "delay_std_s": fields.DELAY_STD_RULE,
            "window_edges_hz": fields.FieldRule(
                "a window edge", "Hz", 0.0, 2 * fields.CENTER_RANGE_HZ[1], open_low=True
            ),
        }
    )

    def __init__(self, fsr_hz: float = 50e9, fsr_tolerance: float = 0.2, window=None):
        self.fsr_hz = fsr_hz
        self.fsr_tolerance = fsr_tolerance
        self.window = window

    @property
    def capabilities(self) -> frozenset[str]:
        """What each window offers, but fitting in chunks: a set reads its sweep whole."""
        return self._window_template().capabilities - {"fit_chunks"}

    @property
    def method_label(self) -> str:
        """The window method, per FSR (e.g. ``"learned per FSR"``)."""
        return f"{type(self._window_template()).method} per FSR"

    def _window_template(self) -> BaseCalibrator:
        return Calibrator() if self.window is None else self.window

    def _check_params(self) -> None:
        super()._check_params()
        check_positive("fsr_tolerance", self.fsr_tolerance, upper=1.0)
        template = self._window_template()
        if (
            not isinstance(template, BaseCalibrator)
            or template.requires
            or isinstance(template, CalibrationSet)
        ):
            raise InputError(
                "window must be an unfitted single-FSR calibrator that needs nothing but the "
                f"readings (e.g. Calibrator(), ConventionalCalibrator()); got {template!r}"
            )

    def _requirement_reason(self) -> str:
        return (
            "a CalibrationSet holds one map per FSR window and needs each reading's "
            "approximate frequency (Hz, within half an FSR, e.g. the laser set point) to pick "
            "the window"
        )

    def _window_calibrator(self, fsr_hz: float) -> BaseCalibrator:
        return clone(self._window_template(), fsr_hz=fsr_hz, fsr_tolerance=WINDOW_FSR_TOLERANCE)

    def get_params_for_file(self) -> dict:
        """Settings as JSON-ready values; the window as its tag and settings."""
        template = self._window_template()
        return {
            "fsr_hz": self.fsr_hz,
            "fsr_tolerance": self.fsr_tolerance,
            "window": {"method": type(template).method, "params": template.get_params_for_file()},
        }

    @classmethod
    def _params_from_file(cls, params: dict) -> dict:
        """Settings of a file: ``window`` as tag and settings; files of 0.1 name the window
        ``method`` with ``retrieval`` and ``port_phases_rad`` beside it."""
        params = dict(params)
        window = params.pop("window", None)
        if window is None:
            tag = params.pop("method", "learned")
            retrieval = params.pop("retrieval", "pinv")
            phases = params.pop("port_phases_rad", None)
            window = {
                "method": tag,
                "params": {"retrieval": retrieval}
                if tag == "learned"
                else {"port_phases_rad": phases},
            }
        if not isinstance(window, dict) or not isinstance(window.get("params"), dict):
            raise InputError(
                "window must be an object with method and params, got "
                f"{shown(window, as_in_file=True)}"
            )
        window_class = calibrator_class(window.get("method"))
        if window_class is None or window_class is cls:
            raise InputError(
                f"unknown window calibration method {shown(window.get('method'), as_in_file=True)}"
            )
        settings = window_class._params_from_file(window["params"])
        fields.check_setting_types(window_class, settings)
        params["window"] = window_class(**settings)
        return params

    # ------------------------------------------------------------------ fitting
    def fit(
        self, powers, frequency_hz, power_monitor_w=None, port_names=None, *, dark_w=None, **cell
    ):
        """Fit the global delay, cut the sweep into one-FSR windows, calibrate each window.

        Parameters
        ----------
        powers : array_like, shape (N, n)
            Port readings (W, or any unit linear in power) over a sweep of at least about
            one FSR (it is cut into ``round(span / FSR)`` windows).
        frequency_hz : array_like, shape (N,)
            Known source frequency of each reading (Hz).
        power_monitor_w : None or array_like, shape (N,)
            Source-power monitor reading (W, or any unit linear in power).
        port_names : None or sequence of str, length n
            Names of the port columns, kept in the calibration file.
        dark_w : None or array_like, shape (n,)
            Per-port dark readings (W), subtracted from every reading.
        **cell
            A reference cell recorded beside the ports (``reference_transmission``,
            ``reference_lines``, ``band_hz``, ``reference_pressure_pa``,
            ``reference_pressure_std_pa``, ``axis_error_hz``), as :meth:`Calibrator.fit
            <wavemeter.Calibrator.fit>` takes it: the set is fitted on the corrected axis
            (``frequency_hz`` None: on the self-calibrated one).

        Returns
        -------
        self

        Warns
        -----
        CalibrationWarning
            Those of the whole-sweep fit, except ``"dispersion"`` (the windows follow it),
            and those of each window (named), except the port health the whole sweep gave.

        Raises
        ------
        EdgeMinimumError
            When the global delay is not inside the FSR bracket (including a side minimum
            of ``J`` on a sweep of several FSRs), or a window's delay is not within
            +-15 % of the global one.
        ValueError
            When the sweep is shorter than half an FSR or a window holds too few readings;
            the message names the window.
        """
        self._check_params()
        raw = check_powers(powers, min_samples=MIN_SAMPLES)

        def fit_on(axis_hz, axis_bandwidth_per_reading=0.0):
            # the windows are fitted by the public fit, on an axis as given: the corrected
            # axis's bandwidth does not reach their fit diagnostics
            del axis_bandwidth_per_reading
            return self._fit_windows(raw, axis_hz, power_monitor_w, port_names, dark_w)

        notes = self._fit_with_cell(
            raw, frequency_hz, cell, fit_on, fsr_tolerance=self.fsr_tolerance, dark_w=dark_w
        )
        for note in notes:
            warnings.warn(note, stacklevel=2)
        return self

    def _fit_windows(self, powers, frequency_hz, power_monitor_w, port_names, dark_w) -> list:
        """The global fit and the windows' (the steps of :meth:`fit`); the warnings."""
        with recorded_calibration_warnings() as caught:
            whole = Calibrator(fsr_hz=self.fsr_hz, fsr_tolerance=self.fsr_tolerance).fit(
                powers, frequency_hz, power_monitor_w, port_names, dark_w=dark_w
            )
        notes = [note for note in caught if note.cause != "dispersion"]
        powers = check_powers(powers, min_samples=MIN_SAMPLES)
        if whole.dark_w_ is not None:
            powers = powers - whole.dark_w_
        frequency = check_frequency(frequency_hz, powers.shape[0])
        monitor = check_monitor(power_monitor_w, powers.shape[0])
        fsr = whole.fsr_hz_
        low, high = whole.span_hz_
        count = round((high - low) / fsr)
        if count < 1:
            raise InputError(
                f"the sweep spans {(high - low) / 1e9:.6g} GHz, less than half the fitted FSR "
                f"({fsr / 1e9:.6g} GHz): a calibration set needs a sweep over whole FSRs; use "
                "wavemeter.Calibrator for a single FSR"
            )
        edges = whole.center_hz_ + (np.arange(count + 1) - count / 2) * fsr
        position = np.floor((frequency - edges[0]) / fsr)
        # the readings are dark-corrected here: windows subtract nothing more (zeros mark
        # the dark as known, so that no window fits offsets of its own)
        window_dark = None if whole.dark_w_ is None else np.zeros(whole.n_ports_)
        windows = []
        for index in range(count):
            rows = position == index
            window = self._window_calibrator(fsr)
            try:
                with recorded_calibration_warnings() as caught:
                    window.fit(
                        powers[rows],
                        frequency[rows],
                        None if monitor is None else monitor[rows],
                        whole.port_names_,
                        dark_w=window_dark,
                    )
            except InputError as exc:
                raise type(exc)(
                    f"{window_label(edges, index)}: {exc}", parameter=exc.parameter
                ) from exc
            # the whole-sweep fit has judged the ports once already
            notes += [
                CalibrationWarning(
                    f"{window_label(edges, index)}: {note}", cause=note.cause, remedy=note.remedy
                )
                for note in caught
                if note.cause != "dead_port"
            ]
            windows.append(window)
        self.delay_s_ = whole.delay_s_
        self.delay_std_s_ = whole.delay_std_s_
        self.diagnostics_ = {
            **whole.diagnostics_,
            "warnings": [note.record() for note in notes],
        }
        self.dark_w_ = whole.dark_w_
        self.offset_w_ = np.zeros(whole.n_ports_)
        self.total_power_range_w_ = whole.total_power_range_w_
        self.fsr_hz_ = fsr
        self.center_hz_ = whole.center_hz_
        self.span_hz_ = whole.span_hz_
        self.n_ports_ = whole.n_ports_
        self.n_samples_ = whole.n_samples_
        self.port_names_ = whole.port_names_
        self.window_edges_hz_ = edges
        self.windows_ = windows
        read = self._frequency_hz(powers, ReadingInputs(coarse_hz=frequency))
        error = wrap_to_period(read - frequency, fsr)
        self.calibration_rms_hz_ = float(np.sqrt(np.mean(error**2)))
        return notes

    def reanchor(self, powers, frequency_hz, *, coarse_hz=None, temperature_k=None):
        """A copy whose windows are re-anchored to readings of reference lines.

        Each reading goes to the window of its known frequency (the exact coarse value);
        every window with readings is re-anchored by its own ``reanchor`` (bias phase, and
        delay where its lines pin it better, :mod:`wavemeter.calibration.models.reanchor`). A
        window without a line gets the phase shift linearly interpolated in window centre
        frequency between the nearest re-anchored windows below and above it (the shifts
        unwrapped in frequency order: a bias change is common to all windows and a delay
        change adds a part linear in frequency), or held from the nearest one beyond the
        outermost; its delay is kept, and the shift's standard error is that of the
        interpolation (model error not included). The global delay and the window edges
        are kept. This set is untouched.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
            Readings of one or more reference lines (W, the unit of the calibration).
        frequency_hz : float or array_like, shape (N,)
            Known frequency of each reading (Hz), inside :meth:`covered_hz`.
        coarse_hz, temperature_k : None, float or array_like, shape (N,)
            Accepted for the common API (checked); not used: the known frequency is the
            coarse value.

        Returns
        -------
        CalibrationSet
            A deep copy; each window's ``diagnostics_["reanchor"]`` tells what it changed
            (``interpolated_from``: indices of the windows its shift came from, empty when it
            had lines) and ``diagnostics_["reanchor"]`` of the set lists every window's.

        Raises
        ------
        InputError
            Naming ``powers``, ``frequency_hz`` (also a frequency outside the calibrated
            span), ``coarse_hz`` or ``temperature_k``; naming ``window`` when the windows
            cannot be re-anchored.
        """
        return reanchored_set(self, powers, frequency_hz, coarse_hz, temperature_k)

    # ------------------------------------------------------------------ reporting
    def _fsr_std_hz(self) -> float | None:
        """Standard error of the global FSR (Hz), from the whole-sweep fit."""
        return None if self.delay_std_s_ is None else self.fsr_hz_**2 * self.delay_std_s_

    def _summary_values(self) -> dict:
        noise = [window.summary().values.get("noise_std_w") for window in self.windows_]
        if any(value is None for value in noise):
            return {}
        mean = float(np.mean([value.value for value in noise]))
        return {"noise_std_w": FitValue(mean, None, "W", "noise estimate (window mean)")}

    def comparison(self, port_phases_rad=None):
        """A set of the window method's comparison, with this set's settings."""
        window = self._window_template().comparison(port_phases_rad=port_phases_rad)
        return CalibrationSet(self.fsr_hz, self.fsr_tolerance, window=window)

    def _window_rows(self, frequency_hz) -> list:
        """``(index, rows)`` of each window with readings, by their (true) frequency."""
        index = self.window_index(frequency_hz)
        return [(number, index == number) for number in np.unique(index)]

    def fringe_panels(self, frequency_hz, powers_w, monitor_w=None, temperature_k=None):
        """Each window's fringes over its own readings (small multiples)."""
        frequency = np.asarray(frequency_hz, dtype=float)
        powers = np.asarray(powers_w, dtype=float)
        panels = []
        for number, rows in self._window_rows(frequency):
            window = self.windows_[number]
            monitor = None if monitor_w is None else np.asarray(monitor_w)[rows]
            (panel,) = window.fringe_panels(frequency[rows], powers[rows], monitor)
            title = f"window {number}: {window.center_hz_ / 1e12:.4f} THz"
            panels.append(dataclasses.replace(panel, title=title))
        return tuple(panels)

    def object_samples(self, powers_w, frequency_hz, temperature_k=None):
        """Each window's samples of the readings whose frequency falls in it."""
        frequency = np.asarray(frequency_hz, dtype=float)
        readings = self._corrected(powers_w)
        parts = [
            self.windows_[number].object_samples(readings[rows], frequency[rows])
            for number, rows in self._window_rows(frequency)
        ]
        if any(part is None for part in parts):
            return None
        return np.concatenate(parts)

    def evaluation_checks(self, powers_w, frequency_hz):
        """Each window's map on its neighbours' readings (:func:`adjacent_evaluation`)."""
        return (adjacent_check(self, powers_w, frequency_hz),)

    def adjacent_evaluation(self, powers_w, frequency_hz, baseline=None) -> dict:
        """Each window's map on its own FSR and on the neighbouring FSRs (paper Fig. 9);
        see :func:`~wavemeter.calibration.methods.set_checks.adjacent_evaluation`."""
        return adjacent_evaluation(self, powers_w, frequency_hz, baseline)

    # ------------------------------------------------------------------ persistence
    def _state(self) -> dict:
        return {
            "delay_s": self.delay_s_,
            "delay_std_s": self.delay_std_s_,
            "window_edges_hz": self.window_edges_hz_.tolist(),
            "windows": [calibrator_fields(window) for window in self.windows_],
        }

    def _set_state(self, state: dict) -> None:
        edges = state_array(state, "window_edges_hz", (None,))
        documents = state.get("windows")
        if edges.size < 2 or np.any(np.diff(edges) <= 0):
            raise InputError("window_edges_hz must be at least 2 increasing finite frequencies")
        if not isinstance(documents, list) or len(documents) != edges.size - 1:
            raise InputError(f"windows must list {edges.size - 1} calibrations, one per window")
        windows = [
            calibrator_from_fields(document, f"window {index}")
            for index, document in enumerate(documents)
        ]
        expected = type(self._window_template())
        for index, window in enumerate(windows):
            if type(window) is not expected or window.n_ports_ != self.n_ports_:
                raise InputError(
                    f"window {index} must be a {expected.method!r} calibration of "
                    f"{self.n_ports_} ports, got {type(window).method!r} with {window.n_ports_}"
                )
        self.delay_s_ = state_float(state, "delay_s", minimum=0.0, open_minimum=True)
        # files of 0.1 have no standard error of the delay
        self.delay_std_s_ = (
            state_float(state, "delay_std_s", minimum=0.0)
            if state.get("delay_std_s") is not None
            else None
        )
        self.window_edges_hz_ = edges
        self.windows_ = windows

"""The estimator contract every calibrator shares: parameters, validation, one prediction API.

Subclasses set ``method`` (the tag in calibration files; a class with a tag registers itself
in :mod:`wavemeter.calibration.registry`), implement ``_fit`` (learn from validated arrays),
``_phase`` (retrieve phase from validated readings) and the pair ``_state`` / ``_set_state``
used by :mod:`wavemeter.calibration.files`.

Every calibrator answers ``predict``, ``phase`` and ``frequency_std_hz`` with the same
keywords (``coarse_hz``, ``temperature_k``). What a class needs besides the readings it
declares in ``requires``; what it can do beyond ``predict`` in ``capabilities``. Callers
(the command line among them) read those declarations instead of testing types.

``fit`` checks the sweep before any method-specific work, in one place for every class:
the design FSR against the sweep's own fringes (:mod:`wavemeter.calibration.fsr_guard`,
which keeps the delay search bounded), then every port's fringe
(:mod:`wavemeter.calibration.diagnostics`); what it finds is kept in ``diagnostics_``,
with the number of readings the checks saw (``"diagnostic_samples"``: every one here; the
learned calibrator checks a long sweep on every k-th reading,
:mod:`wavemeter.calibration.subsample`).
``summary()`` reports the fit (:mod:`wavemeter.calibration.summary`).
"""

from __future__ import annotations

import contextlib
import inspect
import itertools
import math
import numbers
import types
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ..blas import one_blas_thread
from ..exceptions import CalibrationWarning, InputError, WavemeterError
from ..model.cone import phase_to_frequency_hz, wrap_to_period
from ..validation import (
    MIN_SAMPLES,
    check_dark,
    check_fitted,
    check_frequency,
    check_monitor,
    check_per_reading,
    check_positive,
    check_powers,
    reading_array,
)
from .delay_search import DEFAULT_FSR_TOLERANCE
from .diagnostics import check_port_health, port_health
from .flags import SPAN_MARGIN_STD, ReadingFlag, power_flags
from .fsr_guard import MIN_SPAN_FSR, check_design_fsr
from .linear_map import fit_map, object_vectors
from .misfit import MisfitReport, misfit_report
from .registry import register
from .summary import FitReport, FitValue

__all__ = [
    "BaseCalibrator",
    "Readout",
    "StreamReading",
    "MIN_SPAN_FSR",
    "READING_INPUTS",
    "CAPABILITIES",
    "INVALID_READING_CAUSE",
]

#: largest condition number of a loaded map: beyond it the map has lost a dimension
MAX_MAP_CONDITION = 1e10
#: data a calibrator may require per reading, besides the port powers
READING_INPUTS = ("coarse_hz", "temperature_k")
#: what a calibrator may offer besides predict/phase
CAPABILITIES = ("frequency_std", "power_monitor")
#: cause of the warning that a streamed reading could not be read (:meth:`BaseCalibrator.stream`)
INVALID_READING_CAUSE = "invalid_reading"
#: relative margin below the ``OFF_MODEL`` threshold under which a streamed reading's distance
#: to the cone at its retrieved phase proves it on the model without the exact test (that
#: test's distance is exact to ~1e-13 relative, its root tolerance: far inside the margin)
SCREEN_MARGIN = 1e-6


@dataclass(frozen=True, slots=True)
class StreamReading:
    """What :meth:`BaseCalibrator.stream` found for one reading.

    Attributes
    ----------
    frequency_hz : float
        Source frequency (Hz), as ``predict`` gives it; NaN for a reading that cannot be read.
    frequency_std_hz : float
        Its standard deviation (Hz), as ``frequency_std_hz`` gives it; NaN where the
        calibration gives none or the reading cannot be read.
    flags : int
        Quality bits (:class:`~wavemeter.calibration.flags.ReadingFlag`), as ``flags``
        gives them; ``INVALID`` for a reading that cannot be read.
    extras : mapping of str to float
        The calibration's extra outputs (its ``reading_outputs``, e.g. a cascade's
        ``order_error_probability``), by name; NaN for a reading that cannot be read.
    """

    frequency_hz: float
    frequency_std_hz: float
    flags: int
    extras: Mapping[str, float] = field(default_factory=dict)

    @property
    def order_error_probability(self) -> float | None:
        """A cascade's ``extras["order_error_probability"]``; None for other calibrations."""
        return self.extras.get("order_error_probability")


@dataclass(frozen=True)
class Readout:
    """What :meth:`BaseCalibrator.readout` found for a block of readings.

    Attributes
    ----------
    frequency_hz : ndarray, shape (N,)
        Source frequency (Hz); NaN for readings the calibration cannot read.
    frequency_std_hz : ndarray, shape (N,)
        Its standard deviation (Hz); NaN where the calibration gives none.
    flags : ndarray of int64, shape (N,)
        Quality bits (:class:`~wavemeter.calibration.flags.ReadingFlag`).
    extras : dict of str to ndarray, shape (N,)
        The calibration's extra outputs (``reading_outputs``), by name.
    """

    frequency_hz: np.ndarray
    frequency_std_hz: np.ndarray
    flags: np.ndarray
    extras: dict


def checked_port_names(port_names, ports: int) -> list[str]:
    """Names of the port columns: ``p1 .. pn`` by default, else ``ports`` strings."""
    names = [f"p{k + 1}" for k in range(ports)] if port_names is None else list(port_names)
    if len(names) != ports or not all(isinstance(name, str) for name in names):
        raise InputError(f"port_names must be {ports} strings, got {port_names!r}")
    return names


def value_range(values: np.ndarray | None) -> list[float] | None:
    """``[lowest, highest]`` of some values (None for None), as diagnostics keep ranges."""
    return None if values is None else [float(values.min()), float(values.max())]


class BaseCalibrator:
    """Common fit/predict/save machinery; not used on its own."""

    method: ClassVar[str] = ""
    #: per-reading inputs (names from READING_INPUTS) that predict/phase need
    requires: ClassVar[frozenset[str]] = frozenset()
    #: optional features (names from CAPABILITIES) the class provides
    capabilities: ClassVar[frozenset[str]] = frozenset({"power_monitor"})
    #: the method reads absolute frequency without a coarse input (a cascade of stages)
    absolute_frequency: ClassVar[bool] = False
    #: extra per-reading outputs (name -> unit) that ``readout`` and ``stream`` give
    reading_outputs: ClassVar[Mapping[str, str]] = types.MappingProxyType({})
    #: ports with a fringe the method needs among those it reads (the cone model: 3)
    fringe_ports_needed: ClassVar[int] = 3
    #: learned attributes common to every calibrator, saved by every calibration file
    common_attributes: ClassVar[tuple[str, ...]] = (
        "fsr_hz_",
        "center_hz_",
        "span_hz_",
        "n_ports_",
        "n_samples_",
        "port_names_",
        "calibration_rms_hz_",
    )

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if "method" in cls.__dict__ and cls.method:
            register(cls.method, cls)
        declared = cls.__dict__.get("capabilities")
        offered = set(declared) if isinstance(declared, frozenset) else set()
        unknown = (set(cls.requires) - set(READING_INPUTS)) | (offered - set(CAPABILITIES))
        if unknown:
            raise WavemeterError(
                f"{cls.__qualname__} declares unknown inputs or capabilities {unknown}"
            )

    def __init__(self, fsr_hz: float = 50e9):
        self.fsr_hz = fsr_hz

    # ------------------------------------------------------------------ parameters
    @classmethod
    def _param_names(cls) -> list[str]:
        signature = inspect.signature(cls.__init__)
        return [name for name in signature.parameters if name != "self"]

    def get_params(self) -> dict:
        """Settings given to ``__init__``."""
        return {name: getattr(self, name) for name in self._param_names()}

    @property
    def method_label(self) -> str:
        """The method as people read it (the file tag, or e.g. ``"learned per FSR"``)."""
        return type(self).method

    def set_params(self, **params):
        """Change settings given to ``__init__``; returns self (scikit-learn convention).

        Raises
        ------
        InputError
            When a name is not a setting of this class.
        """
        allowed = self._param_names()
        for name, value in params.items():
            if name not in allowed:
                raise InputError(
                    f"{name!r} is not a setting of {type(self).__name__}; settings: "
                    f"{', '.join(allowed)}"
                )
            setattr(self, name, value)
        return self

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        text = f"{type(self).__name__}({params})"
        if hasattr(self, "fsr_hz_"):
            text += (
                f" fitted: FSR {self.fsr_hz_ / 1e9:.6g} GHz, {self.n_ports_} ports, "
                f"{self.n_samples_} samples, RMS {self.calibration_rms_hz_ / 1e6:.3g} MHz"
            )
        return text

    @classmethod
    def _params_from_file(cls, params: dict) -> dict:
        """Settings stored in a calibration file, as ``__init__`` takes them (a class whose
        settings changed maps older files' settings here)."""
        return params

    def get_params_for_file(self) -> dict:
        """Settings as JSON-ready values: arrays and tuples become lists, as JSON reads them."""
        return {
            key: np.asarray(value).tolist() if isinstance(value, (np.ndarray, tuple)) else value
            for key, value in self.get_params().items()
        }

    def _check_params(self) -> None:
        check_positive("fsr_hz", self.fsr_hz)

    def _fsr_tolerance(self) -> float:
        """Relative half width of the FSR bracket the fit searches around ``fsr_hz``."""
        return DEFAULT_FSR_TOLERANCE

    def _ports_read(self, ports: int) -> list[int]:
        """Indices of the ports the method reads (all, unless a method picks some)."""
        return list(range(ports))

    # ------------------------------------------------------------------ fitting
    def fit(
        self,
        powers,
        frequency_hz,
        power_monitor_w=None,
        port_names=None,
        *,
        dark_w=None,
        temperature_k=None,
    ):
        """Learn the calibration from a sweep of known frequencies.

        Parameters
        ----------
        powers : array_like, shape (N, n)
            Port readings (W, or any unit linear in power), ``N >= 4``, ``n >= 3``.
        frequency_hz : array_like, shape (N,)
            Known source frequency of each reading (Hz).
        power_monitor_w : None or array_like, shape (N,)
            Source-power monitor reading (W, or any unit linear in power).
        port_names : None or sequence of str, length n
            Names of the port columns, kept in the calibration file.
        dark_w : None or array_like, shape (n,)
            Per-port dark readings (W, the unit of ``powers``): detector and ADC offsets
            with the source off. Subtracted from every reading, in fit and in predict.
        temperature_k : None, float or array_like, shape (N,)
            Chip temperature of each reading (K). Required by calibrators that name
            ``temperature_k`` in ``requires`` (the thermal one); its range is kept in
            ``diagnostics_["temperature_range_k"]`` by every calibrator.

        Returns
        -------
        self

        Raises
        ------
        InputError
            For readings or settings that are wrong; with ``parameter="fsr_hz"`` when the
            design FSR cannot be right for this sweep (the message gives the sweep's own
            FSR); naming the ports when fewer than 3 carry a fringe.
        EdgeMinimumError
            When the best delay lies outside the FSR bracket searched.

        Warns
        -----
        CalibrationWarning
            Cause ``"dead_port"``: a port is dead, stuck or saturated but 3 others carry
            fringes; or one of :data:`wavemeter.calibration.misfit.CAUSES` when the sweep
            departs from the model (:mod:`wavemeter.calibration.misfit`). The evidence is
            kept in ``diagnostics_``.
        """
        self._check_params()
        raw = check_powers(powers, min_samples=MIN_SAMPLES)
        frequency = check_frequency(frequency_hz, raw.shape[0])
        monitor = check_monitor(power_monitor_w, raw.shape[0])
        n_ports = raw.shape[1]
        dark = check_dark(dark_w, n_ports)
        powers = raw if dark is None else raw - dark
        names = checked_port_names(port_names, n_ports)
        temperature = self._sweep_temperature(temperature_k, n_samples=raw.shape[0])
        with one_blas_thread():
            notes = self._fit_sweep(powers, frequency, monitor, names, dark, temperature)
        for note in notes:
            warnings.warn(note, stacklevel=2)
        return self

    def _fit_sweep(self, powers, frequency_hz, monitor, names, dark, temperature_k) -> list:
        """Fit validated, dark-subtracted readings (N, n), every one of them diagnosed; the
        calibration warnings, not yet issued."""
        scale = None if monitor is None else monitor / monitor.mean()
        # before any delay grid: a design FSR the sweep cannot resolve or contradicts
        estimate = self._check_sweep(powers, frequency_hz, scale, temperature_k)
        span = (float(frequency_hz.min()), float(frequency_hz.max()))
        self._start_fit(span, names, powers.shape[0], dark)
        delay = 1.0 / self.fsr_hz if estimate is None else estimate.delay_s
        self._sweep_temperature_k = temperature_k
        health, notes = self._checked_port_health(powers, frequency_hz, delay, scale)
        self._fit(powers, frequency_hz, monitor)
        corrected = powers - self.offset_w_
        total = corrected.sum(axis=1)
        # the range the flags compare readings with, offset-corrected like them
        self.total_power_range_w_ = (float(total.min()), float(total.max()))
        misfit = self._diagnose_fit(powers, corrected, frequency_hz, scale, delay, temperature_k)
        return self._record_diagnostics(
            estimate,
            health,
            misfit,
            notes,
            temperature_range=value_range(temperature_k),
            diagnosed=powers.shape[0],
        )

    def _start_fit(self, span_hz: tuple[float, float], names: list, samples: int, dark) -> None:
        """The sweep's layout as the fitted attributes keep it; no offsets yet."""
        low, high = span_hz
        self.center_hz_ = 0.5 * (low + high)
        self.span_hz_ = (low, high)
        self.n_ports_ = len(names)
        self.n_samples_ = samples
        self.port_names_ = names
        self.dark_w_ = dark
        self.offset_w_ = np.zeros(len(names))

    def _checked_port_health(self, powers, frequency_hz, delay_s: float, scale):
        """Every port's fringe on the readings diagnosed (:meth:`_port_health`) and the
        warning about the bad ones; raises when too few ports carry a fringe."""
        health = self._port_health(
            powers, frequency_hz, self.center_hz_, delay_s, self.port_names_, scale
        )
        notes = check_port_health(
            [health[k] for k in self._ports_read(self.n_ports_)],
            powers.shape[0],
            needed=self.fringe_ports_needed,
        )
        return health, notes

    def _diagnose_fit(self, powers, corrected, frequency_hz, scale, delay_s, temperature_k):
        """On the readings diagnosed (dark-subtracted, and offset-corrected ``corrected``):
        the RMS error on the sweep and the misfit report, taken into the fit."""
        error = self._sweep_error_hz(corrected, frequency_hz, temperature_k)
        self.calibration_rms_hz_ = float(np.sqrt(np.mean(error**2)))
        misfit = self._misfit_report(powers, frequency_hz, scale, delay_s)
        self._use_misfit_report(misfit)
        del self._sweep_temperature_k
        return misfit

    def _record_diagnostics(
        self, estimate, health, misfit, notes, *, temperature_range, diagnosed: int
    ) -> list:
        """``diagnostics_`` from what the checks found; all the fit's warnings, in order."""
        notes = notes + list(misfit.warnings) + self._fit_notes()
        self.diagnostics_ = {
            "fsr_estimate_hz": None if estimate is None else estimate.fsr_hz,
            "ports": [port.to_dict() for port in health],
            "fit": misfit.to_dict(),
            "temperature_range_k": temperature_range,
            "diagnostic_samples": int(diagnosed),
            **self._method_diagnostics(),
            "warnings": [note.record() for note in notes],
        }
        return notes

    def _sweep_error_hz(self, readings, frequency_hz, temperature_k) -> np.ndarray:
        """Frequency error (Hz) of the sweep's own readings (offset-corrected), modulo the
        FSR: a calibration that needs a coarse frequency is read with the true one."""
        predicted = self._predict_checked(readings, temperature_k)
        return wrap_to_period(predicted - frequency_hz, self.fsr_hz_)

    def _sweep_temperature(self, temperature_k, n_samples: int) -> np.ndarray | None:
        """The sweep's chip temperatures (K) checked, one per reading; None when not given
        (an error for a calibrator that requires them)."""
        if temperature_k is None:
            if "temperature_k" in self.requires:
                raise InputError(
                    f"{type(self).__name__} needs temperature_k (K) for each calibration "
                    "reading: give the chip temperature the sweep was recorded at",
                    parameter="temperature_k",
                )
            return None
        try:
            temperature = check_per_reading("temperature_k", temperature_k, n_samples)
        except InputError as exc:
            raise InputError(str(exc), parameter="temperature_k") from exc
        if np.any(temperature <= 0):
            raise InputError(
                "temperature_k must be > 0 (K, absolute temperature); convert from Celsius",
                parameter="temperature_k",
            )
        return temperature

    def _check_sweep(self, powers, frequency_hz, scale, temperature_k):
        """Check the sweep before any fit: the design FSR against its fringes
        (:func:`~wavemeter.calibration.fsr_guard.check_design_fsr`); a class whose
        fringes move with temperature checks the temperatures too."""
        return check_design_fsr(
            powers,
            frequency_hz,
            fsr_hz=float(self.fsr_hz),
            fsr_tolerance=self._fsr_tolerance(),
            scale=scale,
        )

    def _port_health(self, powers, frequency_hz, center_hz, delay_s, names, scale):
        """Every port's fringe (:func:`~wavemeter.calibration.diagnostics.port_health`) at
        the sweep's own delay."""
        return port_health(powers, frequency_hz, center_hz, delay_s, names, scale)

    def _fit_notes(self) -> list:
        """Method-specific :class:`CalibrationWarning` s of the fit (none by default)."""
        return []

    def _method_diagnostics(self) -> dict:
        """Method-specific entries of ``diagnostics_`` (none by default)."""
        return {}

    def _misfit_report(self, powers, frequency_hz, scale, sweep_delay_s) -> MisfitReport:
        """The sweep against the cone model (:mod:`.misfit`).

        This default fits the least-squares map at the sweep's own delay (the FSR guard's
        estimate, or the design delay): the data are tested against the model, not against
        a method's approximations. Calibrators with a cone map of their own (the learned
        ones) test that map instead. The checks of the pseudo-inverse retrieval (unequal
        noise, an ill-conditioned map) and their remedy (``retrieval="ml"``) concern the
        learned calibrator only, so they are left out here.
        """
        objects = object_vectors(frequency_hz, self.center_hz_, sweep_delay_s, scale)
        return misfit_report(
            powers,
            frequency_hz,
            self.center_hz_,
            sweep_delay_s,
            fit_map(objects, powers),
            scale=scale,
            dark_given=self.dark_w_ is not None,
            weighted_retrieval=True,
        )

    def _use_misfit_report(self, report: MisfitReport) -> None:
        """Take what the fit diagnostics found into the learned state (nothing by default)."""

    def _fit(self, powers: np.ndarray, frequency_hz: np.ndarray, monitor: np.ndarray | None):
        raise NotImplementedError

    # ------------------------------------------------------------------ retrieval
    def _check_readings(self, powers) -> np.ndarray:
        """Validated readings with the dark readings and fitted offsets subtracted."""
        check_fitted(self)
        readings = check_powers(powers, ports=self.n_ports_)
        offset = self._reading_offset_w()
        # most calibrations have none: no copy of the readings then
        return readings - offset if offset.any() else readings

    def _reading_offset_w(self) -> np.ndarray:
        """What every reading carries besides the light (W, per port): dark plus fitted offsets."""
        offset = getattr(self, "offset_w_", None)
        dark = getattr(self, "dark_w_", None)
        total = np.zeros(self.n_ports_) if offset is None else offset
        return total if dark is None else total + dark

    def _check_reading_data(self, powers, coarse_hz, temperature_k) -> tuple[np.ndarray, dict]:
        """Validated readings (N, n) and per-reading inputs (one value or one per reading,
        None where not given); missing required ones raise :class:`InputError` naming them."""
        readings = self._check_readings(powers)
        return readings, self._reading_inputs(coarse_hz, temperature_k, readings.shape[0])

    def _reading_inputs(self, coarse_hz, temperature_k, samples: int) -> dict:
        """The per-reading inputs by name, each None or ``samples`` values; raise when one
        named in ``requires`` is None."""
        given = {"coarse_hz": coarse_hz, "temperature_k": temperature_k}
        missing = [name for name in sorted(self.requires) if given[name] is None]
        if missing:
            raise InputError(
                f"{type(self).__name__} needs {' and '.join(missing)} for each reading "
                f"({self._requirement_reason()}); got None"
            )
        return {
            name: None if value is None else check_per_reading(name, value, samples)
            for name, value in given.items()
        }

    def _requirement_reason(self) -> str:
        return "declared in its requires"

    def phase(self, powers, *, coarse_hz=None, temperature_k=None) -> np.ndarray:
        """Interferometer phase (rad) in (-pi, pi], zero at ``center_hz_``.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
            Port readings, in the unit of the calibration sweep.
        coarse_hz, temperature_k : None, float or array_like, shape (N,)
            Per-reading inputs; required when named in ``requires``, else optional.

        Returns
        -------
        ndarray, shape (N,), rad
        """
        readings, inputs = self._check_reading_data(powers, coarse_hz, temperature_k)
        return self._phase_at(readings, inputs["temperature_k"])

    def _phase(self, powers: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _phase_at(self, powers: np.ndarray, temperature_k: np.ndarray | None) -> np.ndarray:
        """Phase (rad, zero at ``center_hz_``) of validated readings at their temperatures
        (K, or None); only a thermal calibration uses the temperature."""
        return self._phase(powers)

    def predict(self, powers, *, coarse_hz=None, temperature_k=None) -> np.ndarray:
        """Source frequency (Hz) of each reading, within ``center_hz_ +- fsr_hz_/2``.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
            Port readings, in the unit of the calibration sweep.
        coarse_hz, temperature_k : None, float or array_like, shape (N,)
            Per-reading inputs; required when named in ``requires``, else optional.

        Returns
        -------
        ndarray, shape (N,), Hz
        """
        readings, inputs = self._check_reading_data(powers, coarse_hz, temperature_k)
        return self._predict_checked(readings, inputs["temperature_k"])

    def _predict_checked(self, powers: np.ndarray, temperature_k=None) -> np.ndarray:
        """Frequency (Hz) of validated readings at their temperatures (K, or None)."""
        return phase_to_frequency_hz(
            self._phase_at(powers, temperature_k), self.center_hz_, self.fsr_hz_
        )

    def frequency_std_hz(
        self, powers, *, coarse_hz=None, temperature_k=None, include_calibration=True
    ) -> np.ndarray:
        """Per-reading frequency uncertainty (Hz), where ``"frequency_std"`` is a capability.

        Raises
        ------
        InputError
            For a class that does not provide it.
        """
        raise InputError(
            f"{type(self).__name__} ({type(self).method!r}) gives no per-reading uncertainty; "
            "calibrators that do list 'frequency_std' in their capabilities"
        )

    def flags(self, powers, *, coarse_hz=None, temperature_k=None) -> np.ndarray:
        """Quality bit mask per reading (:class:`~wavemeter.calibration.flags.ReadingFlag`).

        Unlike ``predict`` this accepts readings with NaN or no light and marks them
        ``INVALID``; the rules of every bit are in :mod:`wavemeter.calibration.flags`.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
            Port readings, in the unit of the calibration sweep.
        coarse_hz, temperature_k : None, float or array_like, shape (N,)
            Per-reading inputs; required when named in ``requires``, else optional.

        Returns
        -------
        ndarray of int64, shape (N,)
            0 for a reading with nothing to report; ``flags & ReadingFlag.OFF_MODEL`` etc.
        """
        check_fitted(self)
        readings = reading_array(powers, ports=self.n_ports_)
        samples = readings.shape[0]
        corrected = readings - self._reading_offset_w()
        flags = self._light_flags(readings, corrected)
        usable = (flags & ReadingFlag.INVALID) == 0
        inputs = {
            name: None if value is None else value[usable]
            for name, value in self._reading_inputs(coarse_hz, temperature_k, samples).items()
        }
        if usable.any():
            flags[usable] |= self._model_flags(corrected[usable], **inputs)
        return flags

    def _light_flags(self, readings: np.ndarray, corrected: np.ndarray) -> np.ndarray:
        """``INVALID`` (NaN, inf, no light) and ``POWER_RANGE`` bits of readings (N, n), raw and
        less their offsets (:func:`~wavemeter.calibration.flags.power_flags`)."""
        with np.errstate(invalid="ignore"):
            flags = power_flags(
                corrected.sum(axis=1), self._total_power_range_w(), self._offsets_known()
            )
            lit = np.isfinite(readings).all(axis=1) & (readings.sum(axis=1) > 0)
        flags[~lit] |= ReadingFlag.INVALID
        return flags

    def _offsets_known(self) -> bool:
        """Dark readings were given, or offsets fitted (a monitored power that varied)."""
        return getattr(self, "dark_w_", None) is not None or bool(
            np.any(getattr(self, "offset_w_", 0.0))
        )

    def _total_power_range_w(self) -> tuple[float, float] | None:
        """Total power range of the sweep (W); None for files that did not keep it."""
        return getattr(self, "total_power_range_w_", None)

    def _model_flags(self, readings: np.ndarray, coarse_hz, temperature_k) -> np.ndarray:
        """``OUTSIDE_SPAN`` and ``OFF_MODEL`` bits of valid, offset-corrected readings.

        ``OUTSIDE_SPAN``: for a calibration over less than one FSR, a frequency outside the
        sweep by more than ``SPAN_MARGIN_STD`` times :meth:`_span_margin_std_hz`.
        ``OFF_MODEL``: where :meth:`_off_model` has a test.
        """
        flags = np.zeros(readings.shape[0], dtype=np.int64)
        if self._partial_span():
            frequency = self._predict_checked(readings, temperature_k)
            flags |= self._span_flags(frequency, self._span_margin_std_hz(readings, temperature_k))
        off_model = self._off_model(readings)
        if off_model is not None:
            flags[off_model] |= ReadingFlag.OFF_MODEL
        return flags | self._input_flags(coarse_hz, temperature_k)

    def _partial_span(self) -> bool:
        """The sweep covered less than one FSR: frequencies outside it are flagged."""
        low, high = self.span_hz_
        samples = self.n_samples_
        return (high - low) * samples / max(samples - 1, 1) < self.fsr_hz_

    def _span_flags(self, frequency_hz: np.ndarray, margin_std_hz) -> np.ndarray:
        """``OUTSIDE_SPAN`` bits of frequencies (Hz) outside the sweep by more than
        ``SPAN_MARGIN_STD`` times ``margin_std_hz`` (Hz, one or one per frequency)."""
        low, high = self.span_hz_
        margin = SPAN_MARGIN_STD * margin_std_hz
        outside = (frequency_hz < low - margin) | (frequency_hz > high + margin)
        return np.where(outside, np.int64(ReadingFlag.OUTSIDE_SPAN), np.int64(0))

    def _input_flags(self, coarse_hz, temperature_k) -> np.ndarray | int:
        """Bits from the per-reading inputs alone (arrays, or None where not given): none
        here; a thermal calibration flags temperatures outside its calibrated range."""
        return 0

    def _span_margin_std_hz(self, readings: np.ndarray, temperature_k=None) -> np.ndarray | float:
        """Frequency uncertainty (Hz) that widens a partial span before a reading leaves it."""
        return 0.0

    def _off_model(self, readings: np.ndarray) -> np.ndarray | None:
        """Boolean per reading: improbably far from the calibrated model (None: no test)."""
        return None

    def score(self, powers, frequency_hz, *, coarse_hz=None, temperature_k=None) -> float:
        """Negative RMS frequency error (Hz) on readings of known frequency (higher is better).

        Errors are taken modulo the calibrated FSR for a single-FSR calibrator (it measures
        frequency modulo its FSR), absolutely for one that reports absolute frequency (from
        a coarse input, or ``absolute_frequency``).
        """
        predicted = self.predict(powers, coarse_hz=coarse_hz, temperature_k=temperature_k)
        truth = check_frequency(frequency_hz, predicted.shape[0])
        error = predicted - truth
        if not (self.requires & {"coarse_hz"} or self.absolute_frequency):
            error = wrap_to_period(error, self.fsr_hz_)
        return -float(np.sqrt(np.mean(error**2)))

    # ------------------------------------------------------------------ reporting
    def summary(self) -> FitReport:
        """The fit report: learned values with standard errors, settings, diagnostics.

        Returns
        -------
        FitReport
            ``report["fsr_hz"].value`` / ``.stderr`` (Hz), ``report.as_dict()``
            (JSON-ready), ``str(report)`` (aligned text).
        """
        check_fitted(self)
        values = {
            "fsr_hz": FitValue(self.fsr_hz_, self._fsr_std_hz(), "Hz"),
            "design_fsr_hz": FitValue(self._design_fsr_hz(), None, "Hz"),
            "center_hz": FitValue(self.center_hz_, None, "Hz"),
            "calibration_rms_hz": FitValue(self.calibration_rms_hz_, None, "Hz"),
            **self._summary_values(),
        }
        return FitReport(
            method=type(self).method,
            method_label=self.method_label,
            settings=self.get_params_for_file(),
            values=values,
            ports=tuple(self.port_names_),
            samples=self.n_samples_,
            span_hz=tuple(self.span_hz_),
            diagnostics=self.diagnostics_,
            windows=self._window_reports(),
            windows_are=self._windows_are(),
        )

    def _fsr_std_hz(self) -> float | None:
        """Standard error of the fitted FSR (Hz), where the method knows it."""
        return None

    def _design_fsr_hz(self) -> float:
        """The design FSR (Hz) ``fsr_hz_`` is compared with in the summary."""
        return float(self.fsr_hz)

    def _summary_values(self) -> dict:
        """Method-specific learned values for :meth:`summary` (name -> FitValue)."""
        return {}

    def _window_reports(self) -> tuple:
        return ()

    def _windows_are(self) -> str:
        """What :meth:`_window_reports` reports on: ``"windows"`` or ``"stages"``."""
        return "windows"

    # ------------------------------------------------------------------ persistence
    def _state(self) -> dict:
        """Method-specific learned state as JSON-ready values."""
        raise NotImplementedError

    def _set_state(self, state: dict) -> None:
        raise NotImplementedError

    def _reading_model_state(self) -> dict:
        """Dark readings, fitted offsets and the sweep's total power range, JSON-ready."""
        dark = getattr(self, "dark_w_", None)
        power_range = self._total_power_range_w()
        return {
            "dark_w": None if dark is None else dark.tolist(),
            "offset_w": self.offset_w_.tolist(),
            "total_power_range_w": None if power_range is None else list(power_range),
        }

    def _set_reading_model_state(self, state: dict) -> None:
        """Restore :meth:`_reading_model_state`; missing fields (schema 1) mean none."""
        from .files import state_array

        ports = (self.n_ports_,)
        self.dark_w_ = state_array(state, "dark_w", ports) if state.get("dark_w") else None
        self.offset_w_ = (
            state_array(state, "offset_w", ports) if "offset_w" in state else np.zeros(ports)
        )
        if state.get("total_power_range_w") is None:
            self.total_power_range_w_ = None
        else:
            low, high = state_array(state, "total_power_range_w", (2,))
            if not 0 < low <= high:
                raise InputError(
                    f"field 'total_power_range_w' must be 0 < low <= high (W), got {[low, high]}"
                )
            self.total_power_range_w_ = (float(low), float(high))

    def _check_state(self) -> None:
        """Check a loaded state against the model: a full-rank finite (n, 3) map (when the
        method has one) and a delay that is ``1 / fsr_hz`` (when it has one)."""
        matrix = getattr(self, "map_", None)
        if matrix is not None:
            if matrix.shape != (self.n_ports_, 3) or not np.all(np.isfinite(matrix)):
                raise InputError(
                    f"map must be {self.n_ports_} x 3 finite numbers, got shape {matrix.shape}"
                )
            singular = np.linalg.svd(matrix, compute_uv=False)
            if not (singular[-1] > 0 and singular[0] / singular[-1] < MAX_MAP_CONDITION):
                raise InputError(
                    f"map must have full rank 3 (condition number below {MAX_MAP_CONDITION:g}), "
                    f"got singular values {singular.tolist()}"
                )
        delay = getattr(self, "delay_s_", None)
        if delay is not None and not (
            np.isfinite(delay) and delay > 0 and abs(delay * self.fsr_hz_ - 1.0) < 1e-9
        ):
            raise InputError(
                f"delay_s {delay!r} must be > 0 and equal 1 / fsr_hz ({1.0 / self.fsr_hz_!r} s)"
            )

    def save(self, path) -> None:
        """Write the calibration to a versioned JSON file (atomically)."""
        from .files import save_calibration

        save_calibration(self, path)

    # ------------------------------------------------------------------ live readout
    def readout(self, powers, *, coarse_hz=None, temperature_k=None) -> Readout:
        """Frequency, its uncertainty, the quality flags and the extra outputs of readings.

        Unlike ``predict``, a reading that cannot be read (NaN, no light) does not cost the
        others: it gets NaN values and the ``INVALID`` flag.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
            Port readings, in the unit of the calibration sweep.
        coarse_hz, temperature_k : None, float or array_like, shape (N,)
            Per-reading inputs; required when named in ``requires``, else optional.

        Returns
        -------
        Readout
        """
        flags = self.flags(powers, coarse_hz=coarse_hz, temperature_k=temperature_k)
        readings = reading_array(powers, ports=self.n_ports_)
        samples = readings.shape[0]
        frequency = np.full(samples, np.nan)
        std = np.full(samples, np.nan)
        extras = {name: np.full(samples, np.nan) for name in self.reading_outputs}
        usable = (flags & ReadingFlag.INVALID) == 0
        if usable.any():
            given = self._reading_inputs(coarse_hz, temperature_k, samples)
            inputs = {n: None if v is None else v[usable] for n, v in given.items()}
            found = self._readout_valid(readings[usable], inputs)
            frequency[usable], std[usable] = found.frequency_hz, found.frequency_std_hz
            for name in extras:
                extras[name][usable] = found.extras[name]
        return Readout(frequency, std, flags, extras)

    def _readout_valid(self, readings: np.ndarray, inputs: dict) -> Readout:
        """:meth:`readout` of finite, lit readings (no flags needed): ``predict`` and, where
        a capability, ``frequency_std_hz``."""
        frequency = self.predict(readings, **inputs)
        std = (
            self.frequency_std_hz(readings, **inputs)
            if "frequency_std" in self.capabilities
            else np.full(frequency.shape, np.nan)
        )
        return Readout(frequency, std, np.zeros(frequency.shape, np.int64), {})

    def stream(self, rows, *, coarse_hz=None, temperature_k=None) -> Iterator[StreamReading]:
        """Read readings one at a time, as they arrive: one record out for each row in.

        Each row is read only when its record is asked for, so ``rows`` may be endless (a
        live source). The records hold the numbers this calibration's ``predict``,
        ``frequency_std_hz`` and ``flags`` give for the row alone (a cascade's also those of
        ``order_error_probability``), to float64 rounding: each row is read in one pass,
        what stays the same from row to row worked out once per stream
        (:meth:`_stream_reader`).

        Parameters
        ----------
        rows : iterable of array_like, each shape (n,)
            Port readings, in the unit of the calibration sweep.
        coarse_hz, temperature_k : None, float or iterable of float
            Per-reading inputs (Hz, K); required when named in ``requires``. One value for
            every row, or an iterable consumed in step with ``rows``, one value per row.

        Returns
        -------
        iterator of StreamReading
            One record per row, in order.

        Raises
        ------
        InputError
            At the call, for a missing required input or a single value that is not a
            finite number; while iterating, when an iterable of inputs ends before ``rows``.

        Warns
        -----
        CalibrationWarning
            Cause :data:`INVALID_READING_CAUSE`, once per stream, at the first row that
            cannot be read: not ``n`` finite numbers, a per-reading input that is not
            finite, or a reading the calibration refuses (no light, a coarse frequency it
            has no map for). Such a row gives NaN values and the ``INVALID`` flag, with the
            other bits ``flags`` gives it where it gives any.
        """
        check_fitted(self)
        given = {"coarse_hz": coarse_hz, "temperature_k": temperature_k}
        # only whether each input is given matters to this check of the required ones
        self._reading_inputs(*(None if value is None else 0.0 for value in given.values()), 1)
        sources = {}
        for name, value in given.items():
            if value is None:
                sources[name] = itertools.repeat(None)
            elif isinstance(value, (numbers.Real, np.ndarray)) and np.ndim(value) == 0:
                sources[name] = itertools.repeat(float(check_per_reading(name, value, 1)[0]))
            elif isinstance(value, Iterable):
                sources[name] = iter(value)
            else:
                raise InputError(
                    f"{name} must be None, a number or an iterable of numbers (one per row), "
                    f"got {type(value).__name__}"
                )
        if not isinstance(rows, Iterable):
            raise InputError(f"rows must be an iterable of readings, got {type(rows).__name__}")
        ports = self.n_ports_
        read = self._stream_reader()
        nan = float("nan")
        unread_extras = types.MappingProxyType(dict.fromkeys(self.reading_outputs, nan))

        def unread(powers: np.ndarray | None, inputs: dict) -> StreamReading:
            flags = int(ReadingFlag.INVALID)
            if powers is not None:  # the other bits, where flags can tell them
                with contextlib.suppress(InputError):
                    flags |= int(self.flags(powers, **inputs)[0])
            return StreamReading(nan, nan, flags, unread_extras)

        def records() -> Iterator[StreamReading]:
            warned = False
            for index, row in enumerate(rows):
                inputs = {}
                for name, source in sources.items():
                    try:
                        inputs[name] = next(source)
                    except StopIteration:
                        raise InputError(
                            f"{name} ended at reading {index} (zero-based) while rows went on: "
                            "give one value per row"
                        ) from None
                powers = None
                try:
                    try:
                        array = np.asarray(row, dtype=float)
                    except (TypeError, ValueError):
                        raise InputError(f"its port powers are not numbers: {row!r:.60}") from None
                    try:
                        inputs = {n: None if v is None else float(v) for n, v in inputs.items()}
                    except (TypeError, ValueError):
                        raise InputError(f"its inputs are not numbers: {inputs!r:.80}") from None
                    if array.shape != (ports,):
                        raise InputError(f"it has shape {array.shape}, not {ports} port powers")
                    if not np.isfinite(array).all():
                        raise InputError(f"a port power is NaN or inf: {array.tolist()}")
                    bad = [n for n, v in inputs.items() if v is not None and not math.isfinite(v)]
                    if bad:
                        raise InputError(f"{' and '.join(bad)} is not a finite number")
                    powers = array[np.newaxis]
                    record = read(powers, inputs)
                except InputError as exc:
                    record = unread(powers, inputs)
                    if not warned:
                        warned = True
                        warnings.warn(
                            CalibrationWarning(
                                f"reading {index} of the stream (zero-based) cannot be read: "
                                f"{exc}; it, and every later reading that cannot be read, gets "
                                "NaN values and the INVALID flag (without another warning)",
                                cause=INVALID_READING_CAUSE,
                                remedy="check the readings' source: its port count and units, "
                                "and that the light is on",
                            ),
                            stacklevel=2,
                        )
                yield record

        return records()

    def _stream_reader(self) -> Callable[[np.ndarray, dict], StreamReading]:
        """How :meth:`stream` reads one reading; built once per stream.

        Returns
        -------
        callable
            ``read(powers, inputs) -> StreamReading`` for a finite reading ``powers`` (1, n)
            and its per-reading inputs by name (floats, or None where not given); it raises
            :class:`InputError` where the calibration refuses the reading. Here: the
            calibration's own ``predict``, ``frequency_std_hz`` and ``flags`` on the reading;
            the learned family reads it in one pass, a cascade its stages in one (their
            overrides).
        """
        uncertainty = "frequency_std" in self.capabilities

        def read(powers: np.ndarray, inputs: dict) -> StreamReading:
            frequency = float(self.predict(powers, **inputs)[0])
            std = float(self.frequency_std_hz(powers, **inputs)[0]) if uncertainty else math.nan
            return StreamReading(frequency, std, int(self.flags(powers, **inputs)[0]))

        return read

    def _stream_corrector(self) -> Callable[[np.ndarray], np.ndarray]:
        """For a stream: ``corrected(powers)`` of a finite reading (1, n) is the reading less
        its offsets; for a reading without light it raises the error ``predict`` raises."""
        ones = np.ones(self.n_ports_)
        offset = self._reading_offset_w()
        shift = bool(offset.any())

        def corrected(powers: np.ndarray) -> np.ndarray:
            if not (powers @ ones)[0] > 0:
                check_powers(powers)  # its error: the powers sum to zero or less
            return powers - offset if shift else powers

        return corrected

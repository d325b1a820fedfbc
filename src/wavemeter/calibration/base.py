"""The estimator contract every calibrator shares: parameters, validation, one prediction API.

Subclasses set ``method`` (the tag in calibration files; a class with a tag registers itself
in :mod:`wavemeter.calibration.registry`), implement ``_fit`` (learn from validated arrays),
``_phase`` (retrieve phase from validated readings) and the pair ``_state`` / ``_set_state``
used by :mod:`wavemeter.calibration.files`.

Every calibrator answers ``predict``, ``phase`` and ``frequency_std_hz`` with the same
keywords (``coarse_hz``, ``temperature_k``). What a class needs besides the readings it
declares in ``requires``; what it can do beyond ``predict`` in ``capabilities``. Callers
(the command line among them) read those declarations instead of testing types.
"""

from __future__ import annotations

import inspect
from typing import ClassVar

import numpy as np

from ..exceptions import InputError, WavemeterError
from ..model.cone import phase_to_frequency_hz, wrap_to_period
from ..validation import (
    MIN_SAMPLES,
    check_fitted,
    check_frequency,
    check_monitor,
    check_per_reading,
    check_positive,
    check_powers,
)
from .registry import register

__all__ = ["BaseCalibrator", "MIN_SPAN_FSR", "READING_INPUTS", "CAPABILITIES"]

MIN_SPAN_FSR = 0.1
#: data a calibrator may require per reading, besides the port powers
READING_INPUTS = ("coarse_hz", "temperature_k")
#: what a calibrator may offer besides predict/phase
CAPABILITIES = ("frequency_std", "power_monitor")


class BaseCalibrator:
    """Common fit/predict/save machinery; not used on its own."""

    method: ClassVar[str] = ""
    #: per-reading inputs (names from READING_INPUTS) that predict/phase need
    requires: ClassVar[frozenset[str]] = frozenset()
    #: optional features (names from CAPABILITIES) the class provides
    capabilities: ClassVar[frozenset[str]] = frozenset({"power_monitor"})
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
        return f"{type(self).__name__}({params})"

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

    # ------------------------------------------------------------------ fitting
    def fit(self, powers, frequency_hz, power_monitor_w=None, port_names=None):
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

        Returns
        -------
        self
        """
        self._check_params()
        powers = check_powers(powers, min_samples=MIN_SAMPLES)
        frequency = check_frequency(frequency_hz, powers.shape[0])
        monitor = check_monitor(power_monitor_w, powers.shape[0])
        low, high = float(frequency.min()), float(frequency.max())
        if high - low < MIN_SPAN_FSR * self.fsr_hz:
            raise InputError(
                f"the sweep spans {(high - low) / 1e9:.6g} GHz, less than {MIN_SPAN_FSR:g} of the "
                f"FSR ({self.fsr_hz / 1e9:.6g} GHz): sweep over at least "
                f"{MIN_SPAN_FSR * self.fsr_hz / 1e9:.6g} GHz, ideally a whole FSR"
            )
        n_ports = powers.shape[1]
        names = [f"p{k + 1}" for k in range(n_ports)] if port_names is None else list(port_names)
        if len(names) != n_ports or not all(isinstance(name, str) for name in names):
            raise InputError(f"port_names must be {n_ports} strings, got {port_names!r}")
        self.center_hz_ = 0.5 * (low + high)
        self.span_hz_ = (low, high)
        self.n_ports_ = n_ports
        self.n_samples_ = powers.shape[0]
        self.port_names_ = names
        self._fit(powers, frequency, monitor)
        error = wrap_to_period(self._predict_checked(powers) - frequency, self.fsr_hz_)
        self.calibration_rms_hz_ = float(np.sqrt(np.mean(error**2)))
        return self

    def _fit(self, powers: np.ndarray, frequency_hz: np.ndarray, monitor: np.ndarray | None):
        raise NotImplementedError

    # ------------------------------------------------------------------ retrieval
    def _check_readings(self, powers) -> np.ndarray:
        check_fitted(self)
        return check_powers(powers, ports=self.n_ports_)

    def _check_reading_inputs(self, samples: int, coarse_hz, temperature_k) -> dict:
        """Validated per-reading inputs (one value or one per reading); missing required ones
        raise :class:`InputError` naming them."""
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
        readings = self._check_readings(powers)
        self._check_reading_inputs(readings.shape[0], coarse_hz, temperature_k)
        return self._phase(readings)

    def _phase(self, powers: np.ndarray) -> np.ndarray:
        raise NotImplementedError

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
        readings = self._check_readings(powers)
        self._check_reading_inputs(readings.shape[0], coarse_hz, temperature_k)
        return self._predict_checked(readings)

    def _predict_checked(self, powers: np.ndarray) -> np.ndarray:
        return phase_to_frequency_hz(self._phase(powers), self.center_hz_, self.fsr_hz_)

    def frequency_std_hz(
        self, powers, *, coarse_hz=None, temperature_k=None, phase_rad=None
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

    def score(self, powers, frequency_hz, *, coarse_hz=None, temperature_k=None) -> float:
        """Negative RMS frequency error (Hz) on readings of known frequency (higher is better).

        Errors are taken modulo the calibrated FSR for a single-FSR calibrator (it measures
        frequency modulo its FSR), absolutely for one that reports absolute frequency.
        """
        predicted = self.predict(powers, coarse_hz=coarse_hz, temperature_k=temperature_k)
        truth = check_frequency(frequency_hz, predicted.shape[0])
        error = predicted - truth
        if not self.requires & {"coarse_hz"}:
            error = wrap_to_period(error, self.fsr_hz_)
        return -float(np.sqrt(np.mean(error**2)))

    # ------------------------------------------------------------------ persistence
    def _state(self) -> dict:
        """Method-specific learned state as JSON-ready values."""
        raise NotImplementedError

    def _set_state(self, state: dict) -> None:
        raise NotImplementedError

    def _check_state(self) -> None:
        """Check a loaded state: ``map_`` (when the method has one) is finite, (n, 3)."""
        matrix = getattr(self, "map_", None)
        if matrix is not None and (
            matrix.shape != (self.n_ports_, 3) or not np.all(np.isfinite(matrix))
        ):
            raise InputError(f"map must be {self.n_ports_} x 3 finite numbers, got {matrix.shape}")
        if not (self.fsr_hz_ > 0 and self.span_hz_[0] <= self.span_hz_[1]):
            raise InputError("fsr_hz must be > 0 and span_hz must be [low, high]")

    def save(self, path) -> None:
        """Write the calibration to a versioned JSON file (atomically)."""
        from .files import save_calibration

        save_calibration(self, path)

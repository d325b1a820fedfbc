"""The estimator shape every calibrator shares: validation, predict, save, repr.

Subclasses set ``method`` (the tag in calibration files), implement ``_fit`` (learn from
validated arrays), ``_phase`` (retrieve phase from validated readings) and the pair
``_state`` / ``_set_state`` used by :mod:`wavemeter.persistence`.
"""

from __future__ import annotations

import inspect
from typing import ClassVar

import numpy as np

from .cone import phase_to_frequency_hz
from .metrics import frequency_error_hz
from .validation import (
    MIN_SAMPLES,
    check_fitted,
    check_frequency,
    check_monitor,
    check_positive,
    check_powers,
)

__all__ = ["BaseCalibrator", "MIN_SPAN_FSR"]

MIN_SPAN_FSR = 0.1


class BaseCalibrator:
    """Common fit/predict/save machinery; not used on its own."""

    method: ClassVar[str] = ""
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

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({params})"

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
            raise ValueError(
                f"the sweep spans {(high - low) / 1e9:.6g} GHz, less than {MIN_SPAN_FSR:g} of the "
                f"FSR ({self.fsr_hz / 1e9:.6g} GHz): sweep over at least "
                f"{MIN_SPAN_FSR * self.fsr_hz / 1e9:.6g} GHz, ideally a whole FSR"
            )
        n_ports = powers.shape[1]
        names = [f"p{k + 1}" for k in range(n_ports)] if port_names is None else list(port_names)
        if len(names) != n_ports or not all(isinstance(name, str) for name in names):
            raise ValueError(f"port_names must be {n_ports} strings, got {port_names!r}")
        self.center_hz_ = 0.5 * (low + high)
        self.span_hz_ = (low, high)
        self.n_ports_ = n_ports
        self.n_samples_ = powers.shape[0]
        self.port_names_ = names
        self._fit(powers, frequency, monitor)
        error = frequency_error_hz(self._predict_checked(powers), frequency, self.fsr_hz_)
        self.calibration_rms_hz_ = float(np.sqrt(np.mean(error**2)))
        return self

    def _fit(self, powers: np.ndarray, frequency_hz: np.ndarray, monitor: np.ndarray | None):
        raise NotImplementedError

    # ------------------------------------------------------------------ retrieval
    def _check_readings(self, powers) -> np.ndarray:
        check_fitted(self)
        return check_powers(powers, ports=self.n_ports_)

    def phase(self, powers) -> np.ndarray:
        """Interferometer phase (rad) in (-pi, pi], zero at ``center_hz_``.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)

        Returns
        -------
        ndarray, shape (N,), rad
        """
        return self._phase(self._check_readings(powers))

    def _phase(self, powers: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def predict(self, powers) -> np.ndarray:
        """Source frequency (Hz) of each reading, within ``center_hz_ +- fsr_hz_/2``.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)

        Returns
        -------
        ndarray, shape (N,), Hz
        """
        return self._predict_checked(self._check_readings(powers))

    def _predict_checked(self, powers: np.ndarray) -> np.ndarray:
        return phase_to_frequency_hz(self._phase(powers), self.center_hz_, self.fsr_hz_)

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
            raise ValueError(f"map must be {self.n_ports_} x 3 finite numbers, got {matrix.shape}")
        if not (self.fsr_hz_ > 0 and self.span_hz_[0] <= self.span_hz_[1]):
            raise ValueError("fsr_hz must be > 0 and span_hz must be [low, high]")

    def save(self, path) -> None:
        """Write the calibration to a versioned JSON file (atomically)."""
        from .persistence import save_calibration

        save_calibration(self, path)

"""The physics of a simulated interferometer: phase, delay, fields, map and readings.

:class:`InterferometerPhysics` gives an :class:`~wavemeter.simulation.Interferometer`
(whose fields it reads: coupler, splitter, inputs, delay, bias, losses, responsivities,
centre, thermal rates, dark offsets, dispersion and spectral slopes) what follows from
them: the delay and FSR at a temperature, the fringe phase and group delay at a frequency
with dispersion, the fields at the ports and the responsivities with their spectral
slopes, the exact map ``A`` (:meth:`~InterferometerPhysics.true_map`), and the port and
monitor readings of a sweep (:meth:`~InterferometerPhysics.powers`).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InputError
from ..model.cone import delay_phase_rad
from ..validation import as_rng

__all__ = ["InterferometerPhysics", "TERAHERTZ_HZ"]

#: the unit of the spectral slopes: relative change per THz of detuning from ``center_hz``
TERAHERTZ_HZ = 1e12
#: half the step of the central difference of the fringe amplitudes' phase (Hz): their
#: slopes change over THz, so its error is ~(step / THz)^2 of a slope already below 1e-4
FRINGE_STEP_HZ = 1e9


class InterferometerPhysics:
    """What an :class:`~wavemeter.simulation.Interferometer`'s fields give: its phase,
    delay, fields, map and readings (the class parameters of ``Interferometer`` define
    them)."""

    # ------------------------------------------------------------------ properties
    @property
    def ports(self) -> int:
        """Number of egress ports ``n``."""
        return self.output_coupler.shape[0]

    @property
    def true_fsr_hz(self) -> float:
        """The device's free spectral range ``1 / tau`` (Hz)."""
        return 1.0 / self.delay_s

    def _detuning_rad_s(self, f_hz) -> np.ndarray:
        """Angular detuning ``w = 2 pi (f - center_hz)`` (rad/s) of frequencies ``f_hz`` (Hz)."""
        return 2.0 * np.pi * (np.asarray(f_hz, dtype=float) - self.center_hz)

    def _detuning_thz(self, f_hz) -> np.ndarray:
        """Detuning ``d = (f - center_hz) / 1 THz`` of frequencies ``f_hz`` (Hz), the spectral
        slopes' variable."""
        return (np.asarray(f_hz, dtype=float) - self.center_hz) / TERAHERTZ_HZ

    def _temperature_offset_k(self, temperature_k) -> np.ndarray:
        """``T - reference_temperature_k`` (K) of finite temperatures ``temperature_k`` (K)."""
        temperature = np.asarray(temperature_k, dtype=float)
        if not np.all(np.isfinite(temperature)):
            raise InputError("temperature_k must be finite (K)", parameter="temperature_k")
        return temperature - self.reference_temperature_k

    def delay_at(self, temperature_k=None) -> np.ndarray:
        """Delay imbalance (s) at a temperature (K); ``None`` means the reference temperature.

        ``tau(T) = delay_s (1 + thermal_delay_per_k (T - reference_temperature_k))``.

        Parameters
        ----------
        temperature_k : None, float or array_like, shape (N,)
            Chip temperature (K).

        Returns
        -------
        ndarray, shape () or (N,), s
        """
        if temperature_k is None:
            return np.asarray(self.delay_s, dtype=float)
        scale = 1.0 + self.thermal_delay_per_k * self._temperature_offset_k(temperature_k)
        if np.any(scale <= 0):
            raise InputError(
                "temperature_k is so far from reference_temperature_k that the delay "
                f"would not be positive at thermal_delay_per_k={self.thermal_delay_per_k}",
                parameter="temperature_k",
            )
        return self.delay_s * scale

    def true_fsr_hz_at(self, temperature_k=None) -> np.ndarray:
        """The free spectral range ``1 / tau(T)`` (Hz) at a temperature (K), see :meth:`delay_at`.

        With dispersion this is the FSR at ``center_hz``, as :attr:`true_fsr_hz`.
        """
        return 1.0 / self.delay_at(temperature_k)

    def phase_rad(self, f_hz, temperature_k=None) -> np.ndarray:
        """Fringe phase ``t`` (rad) at source frequencies ``f_hz`` (Hz), bias excluded.

        ``t = w tau(T) + dispersion_s2 w**2 / 2`` with ``w = 2 pi (f - center_hz)`` and ``tau(T)``
        from :meth:`delay_at`: the phase of the cone vector that :meth:`true_map` at the same
        temperature maps to the port powers (the bias is a rotation inside the map). Its
        derivative ``dt/dw`` is :meth:`group_delay_s`.

        Parameters
        ----------
        f_hz : array_like, shape (N,)
            Source optical frequency (Hz).
        temperature_k : None, float or array_like, shape (N,)
            Chip temperature (K), scalar or per sample; ``None`` is the reference.

        Returns
        -------
        ndarray, shape (N,), rad
        """
        detuning_rad_s = self._detuning_rad_s(f_hz)
        return delay_phase_rad(f_hz, self.center_hz, self.delay_at(temperature_k)) + (
            0.5 * self.dispersion_s2 * detuning_rad_s**2
        )

    def group_delay_s(self, f_hz, temperature_k=None) -> np.ndarray:
        """Group delay of the imbalance (s) at ``f_hz`` (Hz).

        ``tau(T) + dispersion_s2 2 pi (f - center_hz)``. The local FSR at ``f`` is its
        inverse (:meth:`local_fsr_hz`); at ``center_hz`` that is :meth:`true_fsr_hz_at`
        (:attr:`true_fsr_hz` at the reference temperature).

        Parameters
        ----------
        f_hz : array_like, shape (N,)
            Source optical frequency (Hz).
        temperature_k : None, float or array_like, shape (N,)
            Chip temperature (K), scalar or per sample; ``None`` is the reference.

        Returns
        -------
        ndarray, shape (N,), s
        """
        return self.delay_at(temperature_k) + self.dispersion_s2 * self._detuning_rad_s(f_hz)

    def local_fsr_hz(self, f_hz, temperature_k=None) -> np.ndarray:
        """The local free spectral range (Hz) at ``f_hz`` (Hz): one over :meth:`group_delay_s`.

        Without dispersion it is :meth:`true_fsr_hz_at` at every frequency.

        Parameters
        ----------
        f_hz : array_like, shape (N,)
            Source optical frequency (Hz).
        temperature_k : None, float or array_like, shape (N,)
            Chip temperature (K), scalar or per sample; ``None`` is the reference.

        Returns
        -------
        ndarray, shape (N,), Hz
        """
        return 1.0 / self.group_delay_s(f_hz, temperature_k)

    def fringe_fsr_hz(self, f_hz) -> np.ndarray:
        """The fringes' own period (Hz) at ``f_hz`` (Hz), at the reference temperature.

        2 pi over the slope of the fringe phase: the chip's phase plus the phase of each
        port's fringe amplitude ``A_k0 - i A_k1`` in :meth:`true_map`, weighted by its
        fringe power at ``f_hz``. The couplers' and detectors' phase slopes make it differ
        from :meth:`local_fsr_hz`; it is what a wide-band calibration's ``fsr_hz_`` estimates
        at its centre (the docs' wide-band page, "What the phase coefficients are").

        Parameters
        ----------
        f_hz : array_like, shape (N,)
            Source optical frequency (Hz).

        Returns
        -------
        ndarray, shape (N,), Hz

        Examples
        --------
        >>> import numpy as np
        >>> from wavemeter.simulation import Interferometer
        >>> chip = Interferometer.table1(seed=1).with_spectral("sin", seed=2)
        >>> f_hz = np.array([chip.center_hz])
        >>> shift_hz = chip.fringe_fsr_hz(f_hz) - chip.local_fsr_hz(f_hz)
        >>> bool(0 < abs(shift_hz[0]) < 1e6)  # the couplers' phase slopes: below 1 MHz here
        True
        """
        f_hz = np.atleast_1d(np.asarray(f_hz, dtype=float))
        step_hz = FRINGE_STEP_HZ
        maps = self.true_map(frequency_hz=np.concatenate([f_hz - step_hz, f_hz, f_hz + step_hz]))
        amplitudes = (maps[:, :, 0] - 1j * maps[:, :, 1]).reshape(3, f_hz.size, -1)
        power = np.abs(amplitudes[1]) ** 2
        turn = np.angle(amplitudes[2] / amplitudes[0]) / (2.0 * step_hz)  # rad/Hz per port
        slope = 2.0 * np.pi * self.group_delay_s(f_hz) + np.sum(turn * power, axis=1) / np.sum(
            power, axis=1
        )
        return 2.0 * np.pi / slope

    def _port_fields(self, f_hz=None) -> tuple[np.ndarray, np.ndarray]:
        """Per-port field amplitudes (delayed arm, other arm) at frequencies ``f_hz`` (Hz).

        Shape (n,) each at ``center_hz`` (``f_hz`` None) or without coupler slopes, else
        ``f_hz.shape + (n,)``: the two coupler columns the arms feed, changed by
        ``coupler_slope_per_thz`` (see the class parameters).
        """
        a, b = self.inputs
        loss = 10.0 ** (-np.asarray(self.arm_loss_db, dtype=float) / 20.0)
        arms = self.splitter_amplitudes * loss
        columns = self.output_coupler[:, [a, b]]
        if f_hz is not None and self.coupler_slope_per_thz is not None:
            detuning = self._detuning_thz(f_hz)[..., None, None]
            slope = self.coupler_slope_per_thz[:, [a, b]]
            columns = columns.real * (1.0 + slope.real * detuning) + 1j * (
                columns.imag * (1.0 + slope.imag * detuning)
            )
        return columns[..., 0] * arms[0], columns[..., 1] * arms[1]

    def _responsivity_at(self, f_hz=None) -> np.ndarray:
        """Responsivities at frequencies ``f_hz`` (Hz): shape (n,) at ``center_hz`` (``f_hz``
        None) or without slopes, else ``f_hz.shape + (n,)``; InputError where one would not
        be positive."""
        if f_hz is None or self.responsivity_slope_per_thz is None:
            return self.responsivity
        detuning = self._detuning_thz(f_hz)[..., None]
        responsivity = self.responsivity * (1.0 + self.responsivity_slope_per_thz * detuning)
        if np.any(responsivity <= 0):
            frequency_hz = np.broadcast_to(
                np.asarray(f_hz, dtype=float)[..., None], responsivity.shape
            )
            where = np.nonzero(responsivity <= 0)
            raise InputError(
                f"responsivity_slope_per_thz makes the responsivity of port {where[-1][0] + 1} "
                f"not positive at {frequency_hz[where][0]:.6g} Hz: give smaller slopes or a "
                "narrower band",
                parameter="responsivity_slope_per_thz",
            )
        return responsivity

    def bias_at(self, temperature_k=None) -> np.ndarray:
        """Bias phase (rad) at a temperature (K); ``None`` means the reference temperature.

        ``bias_phase_rad + thermal_phase_rad_per_k (T - reference_temperature_k)``.
        """
        if temperature_k is None:
            return np.asarray(self.bias_phase_rad, dtype=float)
        offset = self._temperature_offset_k(temperature_k)
        return self.bias_phase_rad + self.thermal_phase_rad_per_k * offset

    def true_map(self, temperature_k=None, frequency_hz=None) -> np.ndarray:
        """The exact map ``A`` with ``p = A @ (P [cos t, sin t, sqrt 2])``.

        ``t`` is :meth:`phase_rad` at the same temperature and frequency (``2 pi (f -
        center_hz) tau(T)`` without dispersion): the phase origin is the centre frequency
        and the bias phase at ``temperature_k`` is absorbed into ``A`` as a rotation about
        the cone axis. The output coupler and the responsivities are those at
        ``frequency_hz`` (see ``coupler_slope_per_thz`` and ``responsivity_slope_per_thz``).
        A dark offset is not part of the map.

        Parameters
        ----------
        temperature_k : None, float or array_like, shape (N,)
            Chip temperature (K); ``None`` is the reference. One per frequency only with
            ``frequency_hz`` of shape (N,).
        frequency_hz : None, float or array_like, shape (N,)
            Source optical frequency (Hz); ``None`` is ``center_hz``.

        Returns
        -------
        ndarray, shape (n, 3), or (N, n, 3) for ``frequency_hz`` of shape (N,)
        """
        frequency = None
        if frequency_hz is not None:
            frequency = np.asarray(frequency_hz, dtype=float)
            if frequency.ndim > 1 or not np.all(np.isfinite(frequency)):
                raise InputError(
                    f"frequency_hz must be a finite number or a 1-D array of them (Hz), got "
                    f"shape {frequency.shape}",
                    parameter="frequency_hz",
                )
        bias = self.bias_at(temperature_k)
        if bias.shape not in ((), np.shape(frequency)):
            raise InputError(
                f"temperature_k must be a number or one per frequency_hz (K), got shape "
                f"{bias.shape}",
                parameter="temperature_k",
            )
        delayed, other = self._port_fields(frequency)
        cross = delayed * np.conj(other) * np.exp(1j * bias)[..., None]
        columns = [
            2.0 * cross.real,
            -2.0 * cross.imag,
            (np.abs(delayed) ** 2 + np.abs(other) ** 2) / np.sqrt(2.0),
        ]
        map_ = self._responsivity_at(frequency)[..., None] * np.stack(
            np.broadcast_arrays(*columns), axis=-1
        )
        return np.array(np.broadcast_to(map_, np.shape(frequency) + (self.ports, 3)))

    # ------------------------------------------------------------------ readings
    def powers(
        self,
        f_hz,
        power_w=1e-3,
        noise_w=0.0,
        rng=None,
        temperature_k=None,
        bias_drift_rad=None,
    ) -> np.ndarray:
        """Port readings (W) from the fields, for source frequencies ``f_hz``.

        Each reading is ``responsivity |E|^2 P + dark_offset_w + noise``, where the fields
        interfere at phase :meth:`phase_rad` plus the bias, both at ``temperature_k``, plus
        ``bias_drift_rad``; the output coupler and the responsivity are those at each
        reading's frequency.

        Parameters
        ----------
        f_hz : array_like, shape (N,)
            Source optical frequency (Hz).
        power_w : float or array_like, shape (N,)
            Source power (W), scalar or per sample (fluctuations, drift).
        noise_w : float or array_like, shape (n,)
            Standard deviation of additive white Gaussian detector noise per reading (W),
            one for every port or one per port.
        rng : None, int or numpy.random.Generator
            Source of the noise.
        temperature_k : None, float or array_like, shape (N,)
            Chip temperature (K), scalar or per sample; moves the bias phase by
            ``thermal_phase_rad_per_k`` and the delay by ``thermal_delay_per_k`` per kelvin.
        bias_drift_rad : None, float or array_like, shape (N,)
            Extra bias phase (rad) of each reading, e.g. a thermal drift during a sweep.

        Returns
        -------
        ndarray, shape (N, n), W
        """
        f = np.atleast_1d(np.asarray(f_hz, dtype=float))
        if f.ndim != 1:
            raise InputError(f"f_hz must be 1-D, got shape {f.shape}", parameter="f_hz")
        power = np.broadcast_to(np.asarray(power_w, dtype=float), f.shape)
        if not np.all(np.isfinite(power)) or np.any(power < 0):
            raise InputError("power_w must be finite and non-negative (W)", parameter="power_w")
        noise = np.asarray(noise_w, dtype=float)
        if noise.shape not in ((), (self.ports,)) or not np.all(np.isfinite(noise) & (noise >= 0)):
            raise InputError(
                f"noise_w must be a non-negative number (W) or {self.ports} of them, got {noise_w}",
                parameter="noise_w",
            )
        if temperature_k is not None and np.shape(temperature_k) not in ((), f.shape):
            raise InputError(
                f"temperature_k must be a number or {f.size} of them (K), "
                f"got shape {np.shape(temperature_k)}",
                parameter="temperature_k",
            )
        psi = self.phase_rad(f, temperature_k) + self.bias_at(temperature_k)
        if bias_drift_rad is not None:
            drift = np.asarray(bias_drift_rad, dtype=float)
            if drift.shape not in ((), f.shape) or not np.all(np.isfinite(drift)):
                raise InputError(
                    f"bias_drift_rad must be a finite number or {f.size} of them (rad), "
                    f"got shape {drift.shape}",
                    parameter="bias_drift_rad",
                )
            psi = psi + drift
        delayed, other = self._port_fields(f)
        fields = np.exp(1j * psi)[:, None] * delayed + other
        readings = np.abs(fields) ** 2 * self._responsivity_at(f) * power[:, None]
        if self.dark_offset_w is not None:
            readings = readings + self.dark_offset_w
        if np.any(noise > 0):
            readings = readings + as_rng(rng).normal(0.0, noise, readings.shape)
        return readings

    def monitor(self, power_w, noise_w=0.0, rng=None) -> np.ndarray:
        """Power-monitor reading (W) for source power ``power_w`` (W): ``monitor_ratio * P``."""
        power = np.asarray(power_w, dtype=float)
        reading = self.monitor_ratio * power
        if noise_w > 0:
            reading = reading + as_rng(rng).normal(0.0, noise_w, reading.shape)
        return reading

    def sweep_hz(self, samples: int, span_fsr: float = 1.0) -> np.ndarray:
        """``samples`` frequencies (Hz) evenly over ``span_fsr`` true FSRs about the centre.

        The last point stops one step short of the span, so a one-FSR sweep covers each
        phase once.
        """
        span = span_fsr * self.true_fsr_hz
        return self.center_hz - span / 2 + span * np.arange(samples) / samples

"""Simulated multi-port interferometer with the impairments of the paper's Table 1.

Beyond Table 1 the device can carry hardware faults a real chip has: per-port detector dark
(ADC) offsets, group-delay dispersion of the delay imbalance, unequal detector noise per port
and a bias phase that drifts during a sweep (see :mod:`wavemeter.simulation.drift` for
per-sample drift series). Temperature moves both the bias phase and the delay imbalance;
:data:`THERMAL_PRESETS` (:mod:`wavemeter.simulation.thermal_presets`) holds the thermal
coefficients of two photonic platforms.

Across a wide band (the C band is about 88 FSRs of 50 GHz) the output coupler and the
receivers change slowly with frequency: linear slopes per THz of each coupler entry and of
each responsivity, drawn like Table 1's static spread. :data:`SPECTRAL_PRESETS`
(:mod:`wavemeter.simulation.spectral_presets`) holds realistic dispersion and slopes of a
silicon-nitride chip (see :meth:`Interferometer.with_spectral`).

This module owns the device: its parameters, their checks and its constructors (ideal,
Table 1, thermal, spectral); what follows from them (phase, fields, map, readings) is
:class:`~wavemeter.simulation.interferometer_physics.InterferometerPhysics`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..exceptions import InputError
from ..model.couplers import mmi_2x2, mmi_matrix, port_phases_rad, y_junction
from ..validation import as_rng
from .coupler_draws import perturb_coupler
from .interferometer_physics import InterferometerPhysics
from .spectral_presets import SPECTRAL_PRESETS, SpectralPreset, draw_spectral_slopes
from .thermal_presets import THERMAL_PRESETS

__all__ = ["Interferometer"]

DEFAULT_FSR_HZ = 50e9
DEFAULT_CENTER_HZ = 193.4e12
SPLITTERS = ("mmi", "y")


def _splitter_amplitudes(splitter: str) -> np.ndarray:
    if splitter == "mmi":
        return mmi_2x2()[:, 0]
    if splitter == "y":
        return y_junction()[:, 0]
    raise InputError(f"splitter must be one of {SPLITTERS}, got {splitter!r}")


@dataclass(frozen=True)
class Interferometer(InterferometerPhysics):
    """An unbalanced Mach-Zehnder interferometer with an ``n``-port output coupler.

    A splitter feeds two arms; the delayed arm (delay imbalance ``delay_s``, bias phase
    ``bias_phase_rad``) enters the output coupler at ``inputs[0]``, the other arm at
    ``inputs[1]``; photoreceivers with relative ``responsivity`` read each egress port.
    Port readings are expressed in watts of optical power at the receivers.

    Parameters
    ----------
    output_coupler : ndarray of complex, shape (n, n)
        Transmission matrix of the output coupler.
    splitter_amplitudes : ndarray of complex, shape (2,)
        Field amplitudes the input splitter sends into (delayed arm, other arm).
    inputs : (int, int)
        Zero-based ingress ports of the output coupler fed by the two arms.
    delay_s : float
        Delay imbalance ``tau`` (s); the FSR is ``1 / tau``.
    bias_phase_rad : float
        Phase of the delayed arm relative to the other at ``center_hz`` (rad).
    arm_loss_db : (float, float)
        Power loss of (delayed arm, other arm) in dB.
    responsivity : ndarray, shape (n,)
        Relative photoreceiver responsivities (1 is nominal).
    center_hz : float
        Reference frequency (Hz), the phase origin of :meth:`true_map` and the origin of
        the spectral slopes.
    design_port_phases_rad : ndarray, shape (n,)
        Nominal fringe phases of the design (rad), what the conventional method assumes.
    thermal_phase_rad_per_k : float
        Bias phase change per kelvin away from ``reference_temperature_k`` (rad/K). A
        positive rate moves the fringes to lower frequency on heating, by
        ``thermal_phase_rad_per_k * fsr / (2 pi)`` Hz/K at ``center_hz``.
    reference_temperature_k : float
        Temperature (K) at which the bias phase is ``bias_phase_rad`` and the delay
        ``delay_s``.
    monitor_ratio : float
        Power-monitor reading per watt of source power.
    dark_offset_w : ndarray, shape (n,), optional
        Detector dark/ADC offset of each port (W), added to every reading whatever the source
        power (None: no offset). Stored read-only.
    dispersion_s2 : float
        Group-delay dispersion of the delay imbalance (s^2). The group delay at ``f`` is
        ``delay_s + dispersion_s2 * 2 pi (f - center_hz)`` and the phase gains
        ``dispersion_s2 / 2 * (2 pi (f - center_hz))**2`` (see :meth:`phase_rad`);
        ``delay_s`` and :attr:`true_fsr_hz` stay those at ``center_hz``, the local FSR is
        :meth:`local_fsr_hz`.
    thermal_delay_per_k : float
        Relative change of the delay imbalance per kelvin (1/K): at temperature ``T`` the
        delay is ``delay_s * (1 + thermal_delay_per_k * (T - reference_temperature_k))``
        (see :meth:`delay_at`), so the FSR moves too (:meth:`true_fsr_hz_at`). The
        dispersion ``dispersion_s2`` does not change with temperature.
    coupler_slope_per_thz : ndarray of complex, shape (n, n), optional
        Relative change per THz of the real and imaginary parts of each output-coupler
        entry: at ``f`` the coupler is ``Re(M) * (1 + Re(S) d) + 1j Im(M) * (1 + Im(S) d)``
        with ``d = (f - center_hz) / 1 THz`` (None: no change). Stored read-only.
    responsivity_slope_per_thz : ndarray, shape (n,), optional
        Relative change per THz of each responsivity: at ``f`` it is ``responsivity *
        (1 + slope d)`` (None: no change). Stored read-only.

    Notes
    -----
    A faulty device is a copy of a clean one:
    ``dataclasses.replace(device, dark_offset_w=..., dispersion_s2=...)``.

    Examples
    --------
    >>> import wavemeter as wm
    >>> ideal = wm.Interferometer.ideal(ports=3, fsr_hz=50e9)
    >>> print(f"{ideal.true_fsr_hz / 1e9:.1f} GHz")
    50.0 GHz
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # Table 1: coupler, delay, responsivity
    >>> print(f"{device.true_fsr_hz / 1e9:.2f} GHz")  # the delay is 3 % off its design
    51.50 GHz
    >>> f_hz = device.sweep_hz(200)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> powers.shape
    (200, 3)

    Arm loss and the receivers' responsivities take part of the 1 mW source power:

    >>> print(f"total {powers.sum(axis=1).mean() * 1e3:.2f} mW of 1 mW in")
    total 0.73 mW of 1 mW in
    """

    output_coupler: np.ndarray
    splitter_amplitudes: np.ndarray
    inputs: tuple[int, int] = (0, 2)
    delay_s: float = 1.0 / DEFAULT_FSR_HZ
    bias_phase_rad: float = 0.0
    arm_loss_db: tuple[float, float] = (0.0, 0.0)
    responsivity: np.ndarray | None = None
    center_hz: float = DEFAULT_CENTER_HZ
    design_port_phases_rad: np.ndarray | None = None
    thermal_phase_rad_per_k: float = 0.0
    reference_temperature_k: float = 293.15
    monitor_ratio: float = 0.01
    dark_offset_w: np.ndarray | None = None
    dispersion_s2: float = 0.0
    thermal_delay_per_k: float = 0.0
    coupler_slope_per_thz: np.ndarray | None = None
    responsivity_slope_per_thz: np.ndarray | None = None

    def __post_init__(self):
        coupler = np.array(self.output_coupler, dtype=complex)
        if coupler.ndim != 2 or coupler.shape[0] != coupler.shape[1] or coupler.shape[0] < 3:
            raise InputError(
                f"output_coupler must be a square matrix with at least 3 ports, "
                f"got shape {coupler.shape}"
            )
        n = coupler.shape[0]
        a, b = self.inputs
        if not (0 <= a < n and 0 <= b < n and a != b):
            raise InputError(f"inputs must be two different ports in 0..{n - 1}, got {self.inputs}")
        splitter = np.array(self.splitter_amplitudes, dtype=complex).reshape(-1)
        if splitter.shape != (2,):
            raise InputError(f"splitter_amplitudes must have 2 entries, got {splitter.shape}")
        if not (np.isfinite(self.delay_s) and self.delay_s > 0):
            raise InputError(f"delay_s must be a positive number of seconds, got {self.delay_s}")
        responsivity = np.ones(n) if self.responsivity is None else np.array(self.responsivity)
        if responsivity.shape != (n,) or np.any(responsivity <= 0):
            raise InputError(f"responsivity must be {n} positive numbers, got {responsivity}")
        design = self.design_port_phases_rad
        design = port_phases_rad(coupler, self.inputs) if design is None else np.array(design)
        if design.shape != (n,):
            raise InputError(f"design_port_phases_rad must have {n} entries, got {design.shape}")
        if not np.isfinite(self.dispersion_s2):
            raise InputError(
                f"dispersion_s2 must be a finite number (s^2), got {self.dispersion_s2}",
                parameter="dispersion_s2",
            )
        for name in ("thermal_phase_rad_per_k", "thermal_delay_per_k", "reference_temperature_k"):
            if not np.isfinite(getattr(self, name)):
                raise InputError(
                    f"{name} must be a finite number, got {getattr(self, name)}", parameter=name
                )
        arrays = [coupler, splitter, responsivity, design]
        if self.dark_offset_w is not None:
            offset = np.array(self.dark_offset_w, dtype=float)
            if offset.shape != (n,) or not np.all(np.isfinite(offset)):
                raise InputError(
                    f"dark_offset_w must be {n} finite numbers (W), got {self.dark_offset_w}",
                    parameter="dark_offset_w",
                )
            object.__setattr__(self, "dark_offset_w", offset)
            arrays.append(offset)
        for name, dtype, shape in (
            ("coupler_slope_per_thz", complex, (n, n)),
            ("responsivity_slope_per_thz", float, (n,)),
        ):
            if getattr(self, name) is not None:
                slope = self._slope_array(name, dtype, shape)
                object.__setattr__(self, name, slope)
                arrays.append(slope)
        for array in arrays:
            array.setflags(write=False)
        object.__setattr__(self, "output_coupler", coupler)
        object.__setattr__(self, "splitter_amplitudes", splitter)
        object.__setattr__(self, "responsivity", responsivity)
        object.__setattr__(self, "design_port_phases_rad", design)

    def _slope_array(self, name: str, dtype, shape: tuple[int, ...]) -> np.ndarray:
        """Field ``name`` as a finite array of ``dtype`` and ``shape``, or an InputError."""
        try:
            slope = np.array(getattr(self, name), dtype=dtype)
        except (TypeError, ValueError) as exc:
            raise InputError(
                f"{name} must be numbers (1/THz), got {getattr(self, name)!r}", parameter=name
            ) from exc
        if slope.shape != shape or not np.all(np.isfinite(slope)):
            raise InputError(
                f"{name} must be finite numbers (1/THz) of shape {shape}, got shape {slope.shape}",
                parameter=name,
            )
        return slope

    # ------------------------------------------------------------------ constructors
    @classmethod
    def ideal(
        cls,
        ports: int = 3,
        *,
        fsr_hz: float = DEFAULT_FSR_HZ,
        center_hz: float = DEFAULT_CENTER_HZ,
        bias_phase_rad: float = 0.0,
        splitter: str = "mmi",
        inputs: tuple[int, int] = (0, 2),
    ) -> Interferometer:
        """A perfect device: ideal splitter, ideal ``ports x ports`` MMI, equal receivers.

        Inputs 1 and 3 (zero-based ``(0, 2)``) give equally spaced fringes for 3, 4, 5 and
        8 ports (a 90-degree hybrid for 4).
        """
        return cls(
            output_coupler=mmi_matrix(ports),
            splitter_amplitudes=_splitter_amplitudes(splitter),
            inputs=inputs,
            delay_s=1.0 / fsr_hz,
            bias_phase_rad=bias_phase_rad,
            center_hz=center_hz,
        )

    @classmethod
    def table1(
        cls,
        ports: int = 3,
        seed=None,
        *,
        fsr_hz: float = DEFAULT_FSR_HZ,
        center_hz: float = DEFAULT_CENTER_HZ,
        symmetric_sigma: float = 0.10,
        breaking_sigma: float = 0.01,
        delay_sigma: float = 0.05,
        responsivity_sigma: float = 0.10,
        splitter: str = "mmi",
        inputs: tuple[int, int] = (0, 2),
    ) -> Interferometer:
        """A device with every impairment of the paper's Table 1, drawn from ``seed``.

        Coupler entries (splitter and output MMI): real and imaginary parts scaled by
        ``1 + g + e``, ``g ~ N(0, symmetric_sigma)`` shared by entries the MMI symmetry
        makes equal, ``e ~ N(0, breaking_sigma)`` per entry. Delay ``tau = (1 + d) / fsr_hz``
        with ``d ~ N(0, delay_sigma)``. Responsivities ``1 + r``, ``r ~ N(0,
        responsivity_sigma)``. Bias phase uniform in (-pi, pi]. The design phases stay
        those of the ideal coupler. Noise is a property of the reading, see :meth:`powers`.
        """
        rng = as_rng(seed)
        ideal = cls.ideal(
            ports, fsr_hz=fsr_hz, center_hz=center_hz, splitter=splitter, inputs=inputs
        )
        coupler = perturb_coupler(ideal.output_coupler, rng, symmetric_sigma, breaking_sigma)
        if splitter == "mmi":
            split = perturb_coupler(mmi_2x2(), rng, symmetric_sigma, breaking_sigma)[:, 0]
        else:
            split = ideal.splitter_amplitudes * (1.0 + rng.normal(0.0, breaking_sigma, 2))
        delay_s = (1.0 + rng.normal(0.0, delay_sigma)) / fsr_hz
        responsivity = 1.0 + rng.normal(0.0, responsivity_sigma, ports)
        bias = np.pi - 2.0 * np.pi * rng.random()
        return cls(
            output_coupler=coupler,
            splitter_amplitudes=split,
            inputs=inputs,
            delay_s=delay_s,
            bias_phase_rad=bias,
            responsivity=responsivity,
            center_hz=center_hz,
            design_port_phases_rad=ideal.design_port_phases_rad,
        )

    def with_thermal(self, platform: str) -> Interferometer:
        """This device with the thermal coefficients of ``platform`` (see :data:`THERMAL_PRESETS`).

        The bias rate makes a fringe at ``center_hz`` move by the platform's fringe shift per
        kelvin at this device's FSR: ``thermal_phase_rad_per_k = 2 pi shift_hz_per_k /
        true_fsr_hz``, positive, so heating moves the fringes to lower frequency (the
        optical path grows with temperature). ``thermal_delay_per_k`` is the platform's
        relative delay rate. Everything else is kept.

        Parameters
        ----------
        platform : str
            ``"sin"`` (silicon nitride) or ``"soi"`` (silicon on insulator).

        Returns
        -------
        Interferometer
        """
        if platform not in THERMAL_PRESETS:
            raise InputError(
                f"platform must be one of {tuple(THERMAL_PRESETS)}, got {platform!r}",
                parameter="platform",
            )
        preset = THERMAL_PRESETS[platform]
        return replace(
            self,
            thermal_phase_rad_per_k=2.0 * np.pi * preset.fringe_shift_hz_per_k / self.true_fsr_hz,
            thermal_delay_per_k=preset.delay_per_k,
        )

    def with_spectral(self, platform: str | SpectralPreset = "sin", seed=None) -> Interferometer:
        """This device with the dispersion and spectral slopes of ``platform``, drawn from ``seed``.

        The dispersion is the preset's, for the delay the preset names (``beta_2 L`` grows
        with the imbalance length: scale it for another delay with a preset of your own).
        Coupler slopes are drawn as Table 1 draws the coupler's spread
        (:func:`~wavemeter.simulation.spectral_presets.draw_spectral_slopes`): a relative
        slope of the real and of the imaginary part of each entry, ``g + e`` with ``g ~ N(0,
        coupler_slope_sigma_per_thz)`` shared by the entries the MMI symmetry makes equal
        and ``e ~ N(0, coupler_breaking_sigma_per_thz)`` per entry; then one responsivity
        slope per port, ``N(0, responsivity_slope_sigma_per_thz)``. Everything else is kept.

        Parameters
        ----------
        platform : str or SpectralPreset
            A key of :data:`SPECTRAL_PRESETS` (``"sin"``, silicon nitride) or a preset.
        seed : None, int or numpy.random.Generator
            Source of the slopes. An int seed draws the same numbers as the same seed in
            :meth:`table1`, so the slopes would follow the static spread: give the
            device's own seed as a separate stream
            (``numpy.random.default_rng([seed, stream])``).

        Returns
        -------
        Interferometer
        """
        if isinstance(platform, SpectralPreset):
            preset = platform
        elif platform in SPECTRAL_PRESETS:
            preset = SPECTRAL_PRESETS[platform]
        else:
            raise InputError(
                f"platform must be one of {tuple(SPECTRAL_PRESETS)} or a SpectralPreset, "
                f"got {platform!r}",
                parameter="platform",
            )
        coupler_slope, responsivity_slope = draw_spectral_slopes(self.ports, preset, as_rng(seed))
        return replace(
            self,
            dispersion_s2=preset.dispersion_s2,
            coupler_slope_per_thz=coupler_slope,
            responsivity_slope_per_thz=responsivity_slope,
        )

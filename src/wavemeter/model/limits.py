"""The physical limit: Cramer-Rao lower bound on the frequency from one reading.

Model: ``p = P A [cos t, sin t, sqrt 2] + n`` with white Gaussian noise of standard deviation
``sigma_j`` on port ``j`` (one ``sigma`` for all ports, or one per port) and both ``t`` and
``P`` unknown. With the weights ``W = diag(1 / sigma_j^2)`` the Fisher information on ``t``
with the nuisance ``P`` removed is

    I(t) = a_t' W a_t - (a_t' W a_P)^2 / (a_P' W a_P),
    a_t = P A [-sin t, cos t, 0],   a_P = A [cos t, sin t, sqrt 2],

(for one ``sigma``: ``(|a_t|^2 - (a_t . a_P)^2 / |a_P|^2) / sigma^2``), and the frequency
bound is ``sigma_f = FSR / (2 pi sqrt(I))``.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InputError
from ..validation import check_positive

__all__ = ["crlb_frequency_std", "crlb_ideal_frequency_std", "check_noise_std"]


def check_noise_std(name: str, value, ports: int) -> float | np.ndarray:
    """Detector noise (W): one positive number for every port, or one per port.

    Parameters
    ----------
    name : str
        The parameter's name, for the message.
    value : float or array_like, shape (ports,)
        Standard deviation of the white detector noise (W).
    ports : int
        Number of ports ``n``.

    Returns
    -------
    float, or ndarray of shape (ports,), W

    Examples
    --------
    >>> import wavemeter as wm
    >>> from wavemeter.model import check_noise_std
    >>> check_noise_std("noise_std_w", 5e-7, ports=3)
    5e-07
    >>> print(check_noise_std("noise_std_w", [5e-7, 5e-7, 1e-6], ports=3))
    [5.e-07 5.e-07 1.e-06]
    >>> try:
    ...     check_noise_std("noise_std_w", [5e-7, 5e-7], ports=3)
    ... except wm.InputError as error:
    ...     print(error)
    noise_std_w must be one value or one per port (3), got shape (2,)
    """
    if np.ndim(value) == 0:
        try:
            return check_positive(name, value.item() if isinstance(value, np.ndarray) else value)
        except InputError as exc:
            raise InputError(str(exc), parameter=name) from None
    try:
        noise = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"{name} must be numeric, got {type(value).__name__}", parameter=name
        ) from exc
    if noise.shape != (ports,):
        raise InputError(
            f"{name} must be one value or one per port ({ports}), got shape {noise.shape}",
            parameter=name,
        )
    if not np.all(np.isfinite(noise) & (noise > 0)):
        raise InputError(
            f"{name} must be finite and > 0 for every port, got {noise}", parameter=name
        )
    return noise


def stacked_phase_and_power(matrix: np.ndarray, phase_rad, power):
    """Phases (N,) and power (scalar or (N,)) of N readings with a stack of maps (N, n, 3).

    The phases set N: a stack of another length is refused (naming ``map_``), as are
    phases that are not a vector and a power that is neither one value nor one per phase.
    """
    t = np.asarray(phase_rad, dtype=float)
    if t.ndim != 1:
        raise InputError(
            f"phase_rad must have shape (N,) with a stack of maps, got {t.shape}",
            parameter="phase_rad",
        )
    if matrix.shape[0] != t.size:
        raise InputError(
            f"map_ must hold one map per reading: {matrix.shape[0]} maps for {t.size} phases",
            parameter="map_",
        )
    power = np.asarray(power, dtype=float)
    if power.ndim != 0 and power.shape != t.shape:
        raise InputError(
            f"power must be one value or one per reading ({t.size}), got shape {power.shape}",
            parameter="power",
        )
    return t, power


def _stacked_fsr(fsr_hz, samples: int) -> float | np.ndarray:
    """Free spectral range (Hz): one, or one per map of a stack of ``samples``."""
    if np.ndim(fsr_hz) == 0:
        try:
            return check_positive("fsr_hz", fsr_hz)
        except InputError as exc:
            raise InputError(str(exc), parameter="fsr_hz") from None
    fsr = np.asarray(fsr_hz, dtype=float)
    if fsr.shape != (samples,) or not np.all(np.isfinite(fsr) & (fsr > 0)):
        raise InputError(
            f"fsr_hz must be one finite value > 0, or one per reading ({samples}) each finite "
            f"and > 0, got shape {fsr.shape}",
            parameter="fsr_hz",
        )
    return fsr


def crlb_frequency_std(map_, phase_rad, power, noise_std, fsr_hz) -> np.ndarray:
    """Per-sample Cramer-Rao bound on the frequency standard deviation (Hz).

    Parameters
    ----------
    map_ : array_like, shape (n, 3) or (N, n, 3)
        Map ``A`` per unit of ``power``, or one map per sample (sample ``k`` uses
        ``map_[k]``).
    phase_rad : float or array_like, shape (N,)
        Interferometer phase ``t`` of each sample (rad); shape (N,) with a stack of maps.
    power : float or array_like, shape (N,)
        Source power ``P`` in the unit ``map_`` is scaled by (W for a device's true map;
        1 for a fitted ``Calibrator.map_``, which already holds the calibration power).
    noise_std : float or array_like, shape (n,)
        Detector noise standard deviation per reading (W): one for every port, or one per
        port (the Fisher information then weighs port ``j`` by ``1 / noise_std[j]^2``).
    fsr_hz : float, or array_like of shape (N,) with a stack of maps
        Free spectral range (Hz): one, or the local one of each sample's map.

    Returns
    -------
    ndarray, Hz
        Shape of ``phase_rad`` broadcast with ``power``; (N,) with a stack of maps.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> ideal = wm.Interferometer.ideal(ports=3, fsr_hz=50e9)
    >>> phase_rad = np.linspace(-np.pi, np.pi, 5)
    >>> std_hz = wm.crlb_frequency_std(ideal.true_map(), phase_rad, 1e-3, 5e-7, 50e9)
    >>> print(np.round(std_hz / 1e6, 2))  # MHz per reading, the same at every phase
    [9.75 9.75 9.75 9.75 9.75]
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # an impaired map's bound varies
    >>> std_hz = wm.crlb_frequency_std(device.true_map(), phase_rad, 1e-3, 5e-7, device.true_fsr_hz)
    >>> print(f"{std_hz.min() / 1e6:.1f} to {std_hz.max() / 1e6:.1f} MHz")
    14.1 to 14.7 MHz
    """
    matrix = np.asarray(map_, dtype=float)
    if matrix.ndim not in (2, 3) or matrix.shape[-1] != 3:
        raise InputError(
            f"map_ must have shape (n, 3) or, one map per sample, (N, n, 3), got {matrix.shape}",
            parameter="map_",
        )
    noise_std = check_noise_std("noise_std", noise_std, matrix.shape[-2])
    if matrix.ndim == 2:
        fsr_hz = check_positive("fsr_hz", fsr_hz)
        t = np.asarray(phase_rad, dtype=float)
        power = np.asarray(power, dtype=float)
        zeros = np.zeros_like(t)
        a_t = np.stack([-np.sin(t), np.cos(t), zeros], axis=-1) @ matrix.T * power[..., None]
        a_p = np.stack([np.cos(t), np.sin(t), zeros + np.sqrt(2.0)], axis=-1) @ matrix.T
    else:
        t, power = stacked_phase_and_power(matrix, phase_rad, power)
        fsr_hz = _stacked_fsr(fsr_hz, t.size)
        zeros = np.zeros_like(t)
        tangent = np.stack([-np.sin(t), np.cos(t), zeros], axis=-1)
        cone = np.stack([np.cos(t), np.sin(t), zeros + np.sqrt(2.0)], axis=-1)
        a_t = np.einsum("kji,ki->kj", matrix, tangent) * power[..., None]
        a_p = np.einsum("kji,ki->kj", matrix, cone)
    if np.ndim(noise_std) == 1:  # per-port noise: whiten both directions, then unit noise
        a_t, a_p, noise_std = a_t / noise_std, a_p / noise_std, 1.0
    along = np.einsum("...i,...i->...", a_t, a_p)
    information = (
        np.einsum("...i,...i->...", a_t, a_t) - along**2 / np.einsum("...i,...i->...", a_p, a_p)
    ) / noise_std**2
    return fsr_hz / (2.0 * np.pi * np.sqrt(information))


def crlb_ideal_frequency_std(ports: int, power_w: float, noise_w: float, fsr_hz: float) -> float:
    """Closed-form bound (Hz) for an ideal n-port device: ``FSR sqrt(2 n) sigma / (2 pi P)``.

    An ideal device has ``A = O / sqrt(2 n)`` with ``O`` orthonormal, so ``|a_t|^2 =
    P^2 / (2 n)`` and ``a_t`` is orthogonal to ``a_P``.

    Examples
    --------
    >>> import wavemeter as wm
    >>> for ports in (3, 4):  # the design brief's numbers: 1 mW, 0.5 uW noise, 50 GHz FSR
    ...     std_hz = wm.crlb_ideal_frequency_std(ports, 1e-3, 5e-7, 50e9)
    ...     print(f"{ports}x{ports}: {std_hz / 1e6:.2f} MHz")
    3x3: 9.75 MHz
    4x4: 11.25 MHz
    """
    if ports < 3:
        raise InputError(f"ports must be >= 3, got {ports}", parameter="ports")
    power_w = check_positive("power_w", power_w)
    noise_w = check_positive("noise_w", noise_w)
    return fsr_hz * np.sqrt(2.0 * ports) * noise_w / (2.0 * np.pi * power_w)

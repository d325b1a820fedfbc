"""The object-space model: vectors on the circular cone and how their phase depends on f.

An interferometer reading is ``p = A x`` with ``x = P [cos t, sin t, sqrt(2)]`` on the cone
``x^2 + y^2 - z^2/2 = 0`` (paper Eq. 9-13, 17) and ``t = 2 pi (f - f0) tau`` (Eq. 26 with
the bias absorbed into ``A``). This module owns only that model; fitting ``A`` lives in
:mod:`wavemeter.calibration`.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "cone_vectors",
    "delay_phase_rad",
    "wrap_to_period",
    "wrap_phase_rad",
    "phase_to_frequency_hz",
]

SQRT2 = np.sqrt(2.0)


def cone_vectors(phase_rad, power=1.0) -> np.ndarray:
    """Object vectors ``power * [cos t, sin t, sqrt(2)]`` on the circular cone.

    Parameters
    ----------
    phase_rad : array_like, shape (N,)
        Interferometer phase ``t`` (rad).
    power : float or array_like, shape (N,)
        Source power (W) or any quantity proportional to it.

    Returns
    -------
    ndarray, shape (N, 3)
        (the shapes of ``phase_rad`` and ``power`` broadcast, then 3)

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> x = wm.cone_vectors(np.array([0.0, np.pi / 2]), power=2e-3)
    >>> print(np.round(x * 1e3, 3))  # mW: P [cos t, sin t, sqrt 2]
    [[2.    0.    2.828]
     [0.    2.    2.828]]
    >>> print(np.allclose(x[:, 0] ** 2 + x[:, 1] ** 2 - x[:, 2] ** 2 / 2, 0))  # on the cone
    True
    """
    t = np.asarray(phase_rad, dtype=float)
    scale = np.asarray(power, dtype=float)
    # written in place, column by column: one pass per column and no stacked copies
    vectors = np.empty(np.broadcast_shapes(t.shape, scale.shape) + (3,))
    np.cos(t, out=vectors[..., 0])
    np.sin(t, out=vectors[..., 1])
    vectors[..., 2] = SQRT2
    if scale.ndim or scale != 1.0:
        vectors *= scale[..., None]
    return vectors


def delay_phase_rad(frequency_hz, center_hz: float, delay_s: float) -> np.ndarray:
    """Phase ``2 pi (f - f0) tau`` (rad) of a delay ``tau`` relative to ``f0`` (Eq. 26).

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.model import delay_phase_rad
    >>> f_hz = 193.4e12 + np.array([0.0, 12.5e9, 50e9])
    >>> print(delay_phase_rad(f_hz, 193.4e12, 1 / 50e9) / np.pi)  # a quarter and a whole FSR
    [0.  0.5 2. ]
    """
    return 2.0 * np.pi * (np.asarray(frequency_hz, dtype=float) - center_hz) * delay_s


def wrap_to_period(values, period: float) -> np.ndarray:
    """Wrap values to [-period/2, period/2): the one wrap of phases and frequency errors.

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.model import wrap_to_period
    >>> error_hz = np.array([3e6, 50e9 - 2e6, -50e9 + 1e6])  # two of them one FSR off
    >>> print(wrap_to_period(error_hz, 50e9) / 1e6)
    [ 3. -2.  1.]
    """
    half = 0.5 * period
    return (np.asarray(values, dtype=float) + half) % period - half


def wrap_phase_rad(phase_rad) -> np.ndarray:
    """Wrap phases to [-pi, pi).

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> print(wm.wrap_phase_rad(np.array([3 * np.pi / 2, 2 * np.pi, -np.pi])) / np.pi)
    [-0.5  0.  -1. ]
    """
    return wrap_to_period(phase_rad, 2.0 * np.pi)


def phase_to_frequency_hz(phase_rad, center_hz: float, fsr_hz: float) -> np.ndarray:
    """Frequency (Hz) of a phase on the calibrated FSR: ``f0 + t FSR / (2 pi)``.

    The phase is used as given; with ``t`` in (-pi, pi] the result lies within half an FSR
    of ``center_hz``, so the branch cut sits at ``center_hz +- FSR/2``.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> f_hz = wm.phase_to_frequency_hz(np.array([-np.pi / 2, 0.0, np.pi / 2]), 193.4e12, 50e9)
    >>> print((f_hz - 193.4e12) / 1e9)  # GHz from the centre: a quarter FSR either side
    [-12.5   0.   12.5]
    """
    return center_hz + np.asarray(phase_rad, dtype=float) * (fsr_hz / (2.0 * np.pi))

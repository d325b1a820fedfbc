"""The true fringe phase of a simulated device: what a wide-band calibration's phase
coefficients estimate (the docs' wide-band page, "What the phase coefficients are").

The device's phase ``t`` (delay and dispersion at the centre, from ``group_delay_s`` and
``dispersion_s2``) plus the mean phase of the ports' fringe amplitudes ``z_k = A_k0 - i
A_k1`` of the true map, weighted by ``|z_k|^2`` at the centre; the latter's derivatives at
the centre from a Chebyshev fit over the band (not the calibrator's power series).
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import Chebyshev

__all__ = ["true_fringe_coefficients_s"]

#: Chebyshev nodes sampled, and the degree fitted to the ports' fringe-amplitude phase
NODES = 65
DEGREE = 16


def true_fringe_coefficients_s(
    device, center_hz: float, half_span_hz: float, order: int
) -> np.ndarray:
    """Taylor coefficients ``c_1..c_order`` (s^i) of ``device``'s fringe phase at
    ``center_hz`` in angular detuning, from its true map over ``center_hz +-
    half_span_hz``."""
    nodes = np.cos(np.pi * (np.arange(NODES) + 0.5) / NODES)
    maps = device.true_map(frequency_hz=center_hz + half_span_hz * nodes)
    amplitudes = maps[:, :, 0] - 1j * maps[:, :, 1]
    centre = device.true_map(frequency_hz=np.array([center_hz]))[0]
    power = np.abs(centre[:, 0] - 1j * centre[:, 1]) ** 2
    rotation = Chebyshev.fit(
        nodes, np.unwrap(np.angle(amplitudes), axis=0) @ (power / power.sum()), DEGREE
    )
    orders = np.arange(1, order + 1)
    truth = (
        np.array([rotation.deriv(i)(0.0) for i in orders]) / (2.0 * np.pi * half_span_hz) ** orders
    )
    truth[0] += float(device.group_delay_s(np.array([center_hz]))[0])
    if order > 1:
        truth[1] += device.dispersion_s2
    return truth

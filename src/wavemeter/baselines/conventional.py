"""Todd's conventional method: project the readings with the ideal orthonormal map.

``x_hat = O.T @ p`` with ``O`` built from the nominal port phases (Eq. 15-16), phase
``psi = atan2(x_hat_2, x_hat_1)``. The calibration sweep fixes only what the ideal design
cannot know: the phase origin, the direction (sign) and the FSR, all from the phase-locking
of ``psi`` to the known frequencies: ``(s, FSR)`` maximise
``|mean exp(i (psi_k - s 2 pi (f_k - f0) / FSR))|`` and the origin is the angle of that mean.
"""

from __future__ import annotations

import numpy as np

from ..base import BaseCalibrator
from ..cone import wrap_phase_rad
from ..couplers import equally_spaced_phases_rad, orthonormal_map
from ..delay_search import EdgeMinimumError, search_delay

__all__ = ["ConventionalCalibrator", "phase_locking"]

FSR_TOLERANCE = 0.2


def phase_locking(phase_rad: np.ndarray, offset_hz: np.ndarray, delay_s: float) -> complex:
    """Mean phasor ``mean exp(i (psi - 2 pi offset tau))``; modulus 1 when locked exactly."""
    return complex(np.mean(np.exp(1j * (phase_rad - 2.0 * np.pi * offset_hz * delay_s))))


class ConventionalCalibrator(BaseCalibrator):
    """Conventional (Todd et al.) phase retrieval with the ideal orthonormal map.

    Parameters
    ----------
    fsr_hz : float
        Design FSR (Hz); the sweep refines it within +-20 %.
    port_phases_rad : None or array_like, shape (n,)
        Nominal fringe phase of each port (rad). Default: equally spaced in port order,
        ``2 pi j / n``.

    Attributes
    ----------
    map_ : ndarray, shape (n, 3)
        The ideal orthonormal map ``O`` used for projection.
    direction_ : int
        +1 or -1: the sign relating the ideal phase to increasing frequency.
    phase_origin_rad_ : float
        Ideal-map phase at ``center_hz_`` (rad).
    fsr_hz_, center_hz_, span_hz_, calibration_rms_hz_ : see :class:`wavemeter.Calibrator`.
    """

    method = "conventional"

    def __init__(self, fsr_hz: float = 50e9, port_phases_rad=None):
        self.fsr_hz = fsr_hz
        self.port_phases_rad = port_phases_rad

    def _fit(self, powers, frequency_hz, monitor):
        n = powers.shape[1]
        if self.port_phases_rad is None:
            phases = equally_spaced_phases_rad(n)
        else:
            phases = np.asarray(self.port_phases_rad, dtype=float)
            if phases.shape != (n,):
                raise ValueError(
                    f"port_phases_rad must have one phase per port ({n}), got shape {phases.shape}"
                )
        self.map_ = orthonormal_map(phases)
        ideal_phase = self._ideal_phase(powers)
        offset = frequency_hz - self.center_hz_
        span = self.span_hz_[1] - self.span_hz_[0]
        candidates, edge_error = [], None
        for direction in (1, -1):
            signed = direction * ideal_phase
            try:
                result = search_delay(
                    lambda delay_s, signed=signed: -abs(phase_locking(signed, offset, delay_s)),
                    fsr_hz=self.fsr_hz,
                    fsr_tolerance=FSR_TOLERANCE,
                    span_hz=span,
                )
            except EdgeMinimumError as exc:  # the wrong direction locks on no FSR in range
                edge_error = exc
                continue
            candidates.append((result.cost, direction, result, signed))
        if not candidates:
            raise edge_error
        _, direction, result, signed = min(candidates, key=lambda item: item[0])
        self.direction_ = direction
        self.fsr_hz_ = 1.0 / result.delay_s
        self.phase_origin_rad_ = float(np.angle(phase_locking(signed, offset, result.delay_s)))

    def _ideal_phase(self, powers):
        objects = powers @ self.map_
        return np.arctan2(objects[:, 1], objects[:, 0])

    def _phase(self, powers):
        return wrap_phase_rad(self.direction_ * self._ideal_phase(powers) - self.phase_origin_rad_)

    def _state(self) -> dict:
        return {
            "map": self.map_.tolist(),
            "direction": self.direction_,
            "phase_origin_rad": self.phase_origin_rad_,
        }

    def _set_state(self, state: dict) -> None:
        self.map_ = np.array(state["map"], dtype=float)
        self.direction_ = int(state["direction"])
        self.phase_origin_rad_ = float(state["phase_origin_rad"])

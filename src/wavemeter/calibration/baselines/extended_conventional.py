"""Todd's extended method for a non-ideal coupler: fitted fringes, absolute offsets.

Each port is a fringe ``p_j(f) = c_j + a_j cos(t - phi_j)`` with ``t = 2 pi (f - f0) tau``
(Todd, Seaver and Bucholtz, Electron. Lett. 38, 784, 2002). For a known ``tau`` this model
is linear in ``(c_j, a_j cos phi_j, a_j sin phi_j)``: it is exactly the learned map of
:class:`wavemeter.Calibrator` (columns ``a cos phi``, ``a sin phi`` and ``c / sqrt 2``),
so the sweep is fitted, and ``tau`` searched, by that calibrator.

Retrieval is where the methods differ. Todd subtracts the fitted offsets ``c_j`` (absolute
powers) and forms the in-phase and quadrature combinations with least-squares weights
``W = B+``, ``B = [a cos phi, a sin phi]`` (n x 2): ``[cos t, sin t] ~ W (p - c)``, then
``t = atan2``. The learned method instead solves for the power too. Because ``c`` is
subtracted at the calibration power, a reading at another source power is biased:
at ``P' = k P``, ``W (p - c) = k [cos t, sin t] - (1 - k) W c``, and ``W c`` vanishes only
for an ideal device.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from ...exceptions import InputError
from ..base import BaseCalibrator
from ..learned import Calibrator
from ._labels import FSR_TOLERANCE

__all__ = ["ExtendedConventionalCalibrator"]


class ExtendedConventionalCalibrator(BaseCalibrator):
    """Todd's extended (non-ideal coupler) method with fringe parameters from the sweep.

    Parameters
    ----------
    fsr_hz : float
        Design FSR (Hz); the delay search brackets it within +-20 %.

    Attributes
    ----------
    offsets_w_ : ndarray, shape (n,)
        Fringe offsets ``c_j`` (W) at the calibration source power (with a monitor: at the
        mean monitored power).
    amplitudes_w_ : ndarray, shape (n,)
        Fringe amplitudes ``a_j`` (W).
    port_phases_rad_ : ndarray, shape (n,)
        Fringe phases ``phi_j`` (rad): port ``j`` peaks at ``t = phi_j``.
    quadrature_weights_ : ndarray, shape (2, n)
        Least-squares weights ``W`` giving ``[cos t, sin t]`` from ``p - c``.
    delay_s_ : float
        Fitted delay ``tau`` (s).
    fsr_hz_, center_hz_, span_hz_, calibration_rms_hz_ : see :class:`wavemeter.Calibrator`.
    """

    method = "extended_conventional"

    def __init__(self, fsr_hz: float = 50e9):
        self.fsr_hz = fsr_hz

    def _fit(self, powers, frequency_hz, monitor):
        fringes = Calibrator(fsr_hz=self.fsr_hz, fsr_tolerance=FSR_TOLERANCE).fit(
            powers, frequency_hz, power_monitor_w=monitor
        )
        in_phase, quadrature, axial = fringes.map_.T
        self.delay_s_ = fringes.delay_s_
        self.fsr_hz_ = 1.0 / fringes.delay_s_
        self._set_fringes(
            offsets_w=np.sqrt(2.0) * axial,
            amplitudes_w=np.hypot(in_phase, quadrature),
            port_phases_rad=np.arctan2(quadrature, in_phase),
        )

    def _set_fringes(self, offsets_w, amplitudes_w, port_phases_rad) -> None:
        """Store the fringe parameters and derive the weights (same path for fit and load)."""
        self.offsets_w_ = offsets_w
        self.amplitudes_w_ = amplitudes_w
        self.port_phases_rad_ = port_phases_rad
        fringe_matrix = np.column_stack(
            [amplitudes_w * np.cos(port_phases_rad), amplitudes_w * np.sin(port_phases_rad)]
        )
        self.quadrature_weights_ = linalg.pinv(fringe_matrix)

    def _phase(self, powers):
        quadratures = (powers - self.offsets_w_) @ self.quadrature_weights_.T
        return np.arctan2(quadratures[:, 1], quadratures[:, 0])

    def _state(self) -> dict:
        return {
            "offsets_w": self.offsets_w_.tolist(),
            "amplitudes_w": self.amplitudes_w_.tolist(),
            "port_phases_rad": self.port_phases_rad_.tolist(),
            "delay_s": self.delay_s_,
        }

    def _set_state(self, state: dict) -> None:
        fringes = [
            np.array(state[key], dtype=float)
            for key in ("offsets_w", "amplitudes_w", "port_phases_rad")
        ]
        if any(v.shape != (self.n_ports_,) or not np.all(np.isfinite(v)) for v in fringes):
            raise InputError(
                f"offsets_w, amplitudes_w and port_phases_rad must be {self.n_ports_} finite "
                "numbers each"
            )
        self.delay_s_ = float(state["delay_s"])
        self._set_fringes(*fringes)

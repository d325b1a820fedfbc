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

from ....exceptions import InputError
from ...contract.base import BaseCalibrator
from ...contract.summary import FitValue
from ...files import fields
from ...files.document import state_array, state_float
from ...fitting.steps import SweepFitMixin
from ...models.delay_search import DEFAULT_FSR_TOLERANCE
from ...models.learned_fit import fit_learned_map
from ._compared import ComparedWithLearnedMixin

__all__ = ["ExtendedConventionalCalibrator"]


class ExtendedConventionalCalibrator(ComparedWithLearnedMixin, SweepFitMixin, BaseCalibrator):
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
    delay_std_s_ : float or None
        Its standard error (s), as for :class:`wavemeter.Calibrator`.
    fsr_hz_, center_hz_, span_hz_, calibration_rms_hz_ : see :class:`wavemeter.Calibrator`.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> cal = wm.ExtendedConventionalCalibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> print(f"fitted FSR {cal.fsr_hz_ / 1e9:.2f} GHz, true {device.true_fsr_hz / 1e9:.2f} GHz")
    fitted FSR 51.51 GHz, true 51.50 GHz

    With the fringe parameters taken from the sweep, Todd's extended method reads this
    device near the learned map (17 MHz; the conventional one: 545 MHz):

    >>> test_hz = f_hz[5::20] + 1e8
    >>> test = device.powers(test_hz, power_w=1e-3, noise_w=5e-7, rng=2)
    >>> print(f"RMS error {np.sqrt(np.mean((cal.predict(test) - test_hz) ** 2)) / 1e6:.0f} MHz")
    RMS error 16 MHz
    """

    method = "extended_conventional"
    #: the largest fringe amplitude is the power scale
    state_rules = fields.rule_table(
        {
            "amplitudes_w": (
                fields.ScaleRule(
                    "a fringe amplitude", fields.largest_magnitude, "the largest fringe amplitude"
                ),
                fields.FieldRule("a fringe amplitude", "W", 0.0, 1.0, scale="power_w"),
            ),
            "offsets_w": fields.OFFSET_RULE,
            "port_phases_rad": fields.ANGLE_RULE,
            "delay_s": fields.DELAY_RULE,
            "delay_std_s": fields.DELAY_STD_RULE,
        }
    )

    def __init__(self, fsr_hz: float = 50e9):
        self.fsr_hz = fsr_hz

    def _learn(self, sweep):
        powers, frequency_hz, monitor = sweep.powers_w, sweep.frequency_hz, sweep.monitor_w
        fringes = fit_learned_map(
            powers,
            frequency_hz,
            self.center_hz_,
            fsr_hz=self.fsr_hz,
            fsr_tolerance=DEFAULT_FSR_TOLERANCE,
            scale=None if monitor is None else monitor / monitor.mean(),
        )
        in_phase, quadrature, axial = fringes.map_.T
        self.delay_s_ = fringes.delay_s
        self.delay_std_s_ = fringes.delay_std_s
        self.fsr_hz_ = 1.0 / fringes.delay_s
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

    def _fsr_std_hz(self) -> float | None:
        return None if self.delay_std_s_ is None else self.fsr_hz_**2 * self.delay_std_s_

    def _summary_values(self) -> dict:
        return {"delay_s": FitValue(self.delay_s_, self.delay_std_s_, "s")}

    def _state(self) -> dict:
        return {
            "offsets_w": self.offsets_w_.tolist(),
            "amplitudes_w": self.amplitudes_w_.tolist(),
            "port_phases_rad": self.port_phases_rad_.tolist(),
            "delay_s": self.delay_s_,
            "delay_std_s": self.delay_std_s_,
        }

    def _set_state(self, state: dict) -> None:
        fringes = [
            state_array(state, key, (self.n_ports_,))
            for key in ("offsets_w", "amplitudes_w", "port_phases_rad")
        ]
        self.delay_s_ = state_float(state, "delay_s", minimum=0.0, open_minimum=True)
        # files of 0.1 have no standard error of the delay
        self.delay_std_s_ = (
            state_float(state, "delay_std_s", minimum=0.0)
            if state.get("delay_std_s") is not None
            else None
        )
        self._set_fringes(*fringes)
        if not np.all(np.isfinite(self.quadrature_weights_)):
            raise InputError("the fringes of amplitudes_w and port_phases_rad are degenerate")

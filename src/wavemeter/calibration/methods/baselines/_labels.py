"""Fix the phase origin, direction and FSR of a raw phase from the calibration labels.

Several baselines produce a phase ``psi`` from the readings alone (an ideal projection, an
ellipse fit) that is right up to an origin, a direction and the frequency scale. The
calibration sweep fixes those three by phase locking: ``(s, tau)`` maximise the modulus
of the mean phasor ``z = mean_k z_k``, ``z_k = exp(i (s psi_k - 2 pi (f_k - f0) tau))``,
and the origin is the angle of ``z``, so that ``t = s psi - origin`` is zero at ``f0`` and
grows with frequency. The search minimises the equivalent spread
``mean |z_k - z|^2 = 1 - |z|^2``, formed from the deviations so that it keeps full relative
precision near a perfect lock (noiseless data lock to machine precision).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ....exceptions import InputError, shown
from ....model.cone import wrap_phase_rad
from ...contract.base import BaseCalibrator
from ...contract.summary import FitValue
from ...files import fields
from ...files.state import state_float
from ...fitting.steps import SweepFitMixin
from ...models.delay_search import DEFAULT_FSR_TOLERANCE, EdgeMinimumError, search_delay
from ._compared import ComparedWithLearnedMixin

__all__ = [
    "LabelLockedCalibrator",
    "PhaseLock",
    "lock_phase",
    "locking_spread",
    "phase_locking",
]


def phase_locking(phase_rad: np.ndarray, offset_hz: np.ndarray, delay_s: float) -> complex:
    """Mean phasor ``mean exp(i (psi - 2 pi offset tau))``; modulus 1 when locked exactly."""
    return complex(np.mean(np.exp(1j * (phase_rad - 2.0 * np.pi * offset_hz * delay_s))))


def locking_spread(phase_rad: np.ndarray, offset_hz: np.ndarray, delay_s: float) -> float:
    """Spread ``mean |z_k - mean z|^2 = 1 - |phase_locking|^2`` of the phasors, in [0, 1]."""
    phasors = np.exp(1j * (phase_rad - 2.0 * np.pi * offset_hz * delay_s))
    deviation = phasors - phasors.mean()
    return float(np.mean(deviation.real**2 + deviation.imag**2))


@dataclass(frozen=True)
class PhaseLock:
    """Outcome of :func:`lock_phase`.

    Attributes
    ----------
    direction : int
        +1 or -1: the sign that makes the raw phase grow with frequency.
    delay_s : float
        Delay ``tau`` (s) of the best lock; the FSR is ``1 / tau``.
    origin_rad : float
        Signed raw phase at the reference frequency (rad).
    locking : float
        Modulus of the mean phasor, in [0, 1]; 1 for a raw phase exactly linear in frequency.
    """

    direction: int
    delay_s: float
    origin_rad: float
    locking: float


def lock_phase(
    phase_rad,
    offset_hz,
    *,
    fsr_hz: float,
    span_hz: float,
    fsr_tolerance: float = DEFAULT_FSR_TOLERANCE,
) -> PhaseLock:
    """Direction, delay and origin that lock a raw phase to known frequencies.

    Parameters
    ----------
    phase_rad : array_like, shape (N,)
        Raw phase of each calibration reading (rad), any origin and direction.
    offset_hz : array_like, shape (N,)
        Known frequency of each reading minus the reference frequency ``f0`` (Hz).
    fsr_hz : float
        Design FSR (Hz), the centre of the searched bracket.
    span_hz : float
        Frequency span of the sweep (Hz); sets the scan step of the delay search.
    fsr_tolerance : float
        Relative half width of the FSR bracket, in (0, 1).

    Returns
    -------
    PhaseLock

    Raises
    ------
    EdgeMinimumError
        When neither direction locks on an FSR inside the bracket.
    """
    phase = np.asarray(phase_rad, dtype=float)
    offset = np.asarray(offset_hz, dtype=float)
    candidates, edge_error = [], None
    for direction in (1, -1):
        signed = direction * phase
        try:
            result = search_delay(
                lambda delay_s, signed=signed: locking_spread(signed, offset, delay_s),
                fsr_hz=fsr_hz,
                fsr_tolerance=fsr_tolerance,
                span_hz=span_hz,
            )
        except EdgeMinimumError as exc:  # the wrong direction locks on no FSR in range
            edge_error = exc
            continue
        candidates.append((result.cost, direction, result.delay_s, signed))
    if not candidates:
        raise edge_error
    _, direction, delay_s, signed = min(candidates, key=lambda item: item[0])
    phasor = phase_locking(signed, offset, delay_s)
    return PhaseLock(
        direction=direction,
        delay_s=delay_s,
        origin_rad=float(np.angle(phasor)),
        locking=abs(phasor),
    )


class LabelLockedCalibrator(ComparedWithLearnedMixin, SweepFitMixin, BaseCalibrator):
    """A calibrator whose model yields a raw phase right up to origin, direction and FSR.

    Subclasses fit their model in ``_fit``, then call :meth:`_lock_to_labels`; they
    implement ``_raw_phase(powers) -> rad``. Learned here: ``direction_``, ``fsr_hz_`` and
    ``phase_origin_rad_``.
    """

    state_rules = fields.rule_table(
        {
            "direction": fields.FieldRule("the phase direction", "", choices=(1, -1)),
            "phase_origin_rad": fields.FieldRule("the phase origin", "rad", -np.pi, np.pi),
        }
    )

    def _raw_phase(self, powers: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _lock_to_labels(self, powers: np.ndarray, frequency_hz: np.ndarray) -> None:
        lock = lock_phase(
            self._raw_phase(powers),
            frequency_hz - self.center_hz_,
            fsr_hz=self.fsr_hz,
            span_hz=self.span_hz_[1] - self.span_hz_[0],
        )
        self.direction_ = lock.direction
        self.fsr_hz_ = 1.0 / lock.delay_s
        self.phase_origin_rad_ = lock.origin_rad

    def _phase(self, powers):
        return wrap_phase_rad(self.direction_ * self._raw_phase(powers) - self.phase_origin_rad_)

    def _summary_values(self) -> dict:
        return {
            "direction": FitValue(float(self.direction_)),
            "phase_origin_rad": FitValue(self.phase_origin_rad_, None, "rad"),
        }

    def _lock_state(self) -> dict:
        return {"direction": self.direction_, "phase_origin_rad": self.phase_origin_rad_}

    def _set_lock_state(self, state: dict) -> None:
        direction = state.get("direction")
        if isinstance(direction, bool) or direction not in (1, -1):
            raise InputError(
                f"field 'direction' must be 1 or -1, got {shown(direction, as_in_file=True)}"
            )
        self.direction_ = int(direction)
        self.phase_origin_rad_ = state_float(
            state, "phase_origin_rad", minimum=-np.pi, maximum=np.pi
        )

"""Todd's conventional method: project the readings with the ideal orthonormal map.

``x_hat = O.T @ p`` with ``O`` built from the nominal port phases (Eq. 15-16), phase
``psi = atan2(x_hat_2, x_hat_1)``. The calibration sweep fixes only what the ideal design
cannot know: the phase origin, the direction (sign) and the FSR, all from the phase-locking
of ``psi`` to the known frequencies (:func:`wavemeter.baselines._labels.lock_phase`).
"""

from __future__ import annotations

import numpy as np

from ....exceptions import InputError
from ....model.couplers import equally_spaced_phases_rad, orthonormal_map
from ...files import fields
from ...files.document import state_array
from ..figures import MapSamplesMixin
from ._labels import LabelLockedCalibrator, phase_locking

__all__ = ["ConventionalCalibrator", "phase_locking"]


class ConventionalCalibrator(MapSamplesMixin, LabelLockedCalibrator):
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

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> conventional = wm.ConventionalCalibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> learned = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)

    On an impaired device the ideal map costs an order of magnitude and more against the
    learned one (the paper's claim), which reads at the Cramer-Rao bound (14 MHz):

    >>> test_hz = f_hz[5::20] + 1e8
    >>> test = device.powers(test_hz, power_w=1e-3, noise_w=5e-7, rng=2)
    >>> for cal in (conventional, learned):
    ...     rms_hz = np.sqrt(np.mean((cal.predict(test) - test_hz) ** 2))
    ...     print(f"{cal.method}: {rms_hz / 1e6:.0f} MHz")
    conventional: 545 MHz
    learned: 17 MHz
    """

    method = "conventional"
    #: the ideal map's columns are unit vectors: no power scale
    state_rules = fields.rule_table(
        {"map": fields.FieldRule("an entry of the ideal map", "", high=1.0, magnitude=True)}
    )

    def __init__(self, fsr_hz: float = 50e9, port_phases_rad=None):
        self.fsr_hz = fsr_hz
        self.port_phases_rad = port_phases_rad

    def _learn(self, sweep):
        powers, frequency_hz = sweep.powers_w, sweep.frequency_hz
        n = powers.shape[1]
        if self.port_phases_rad is None:
            phases = equally_spaced_phases_rad(n)
        else:
            phases = np.asarray(self.port_phases_rad, dtype=float)
            if phases.shape != (n,):
                raise InputError(
                    f"port_phases_rad must have one phase per port ({n}), got shape {phases.shape}"
                )
        self.map_ = orthonormal_map(phases)
        self._lock_to_labels(powers, frequency_hz)

    def _raw_phase(self, powers):
        objects = powers @ self.map_
        return np.arctan2(objects[:, 1], objects[:, 0])

    def _state(self) -> dict:
        return {"map": self.map_.tolist(), **self._lock_state()}

    def _set_state(self, state: dict) -> None:
        self.map_ = state_array(state, "map", (self.n_ports_, 3))
        self._set_lock_state(state)

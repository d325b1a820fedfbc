"""Two calibrators written outside wavemeter, registered through its entry points.

``FixedDelayCalibrator`` implements only the documented minimal interface: a tag, its
settings, ``_learn`` (what it learns from a checked sweep), ``_phase`` (the phase of
readings) and ``_state``/``_set_state`` (what its file keeps). It fits the learned map at
the design FSR, without searching the delay. ``MlCalibrator`` is ``wavemeter.Calibrator``
under a tag of its own, reading by the cone maximum likelihood by default.
"""

import numpy as np

import wavemeter as wm
from wavemeter.calibration import BaseCalibrator, SweepFitMixin
from wavemeter.model import cone_vectors, delay_phase_rad


class FixedDelayCalibrator(SweepFitMixin, BaseCalibrator):
    """The learned map at the design FSR (no delay search)."""

    method = "toy_fixed_delay"

    def __init__(self, fsr_hz=50e9):
        self.fsr_hz = fsr_hz

    def _learn(self, sweep):
        phase = delay_phase_rad(sweep.frequency_hz, self.center_hz_, 1.0 / self.fsr_hz)
        power = 1.0 if sweep.scale is None else sweep.scale
        solution, *_ = np.linalg.lstsq(cone_vectors(phase, power), sweep.powers_w, rcond=None)
        self.map_ = solution.T
        self.fsr_hz_ = float(self.fsr_hz)

    def _phase(self, readings):
        objects = readings @ np.linalg.pinv(self.map_).T
        return np.arctan2(objects[:, 1], objects[:, 0])

    def _state(self):
        return {"map": self.map_.tolist()}

    def _set_state(self, state):
        self.map_ = np.asarray(state["map"], dtype=float)


class MlCalibrator(wm.Calibrator):
    """The learned calibration, reading by the cone maximum likelihood by default."""

    method = "toy_ml"

    def __init__(self, fsr_hz=50e9, fsr_tolerance=0.2, search="golden", xtol=1e-12, retrieval="ml"):
        super().__init__(fsr_hz, fsr_tolerance, search, xtol, retrieval)

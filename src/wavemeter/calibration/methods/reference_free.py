"""A calibrator that learns the cone from the powers alone: phase without a frequency axis.

:class:`ReferenceFreeCalibrator` fits the cone of the readings without labels
(:func:`~wavemeter.calibration.models.cone_fit.fit_cone`: varying source power and, on
request, detector offsets).
Given the sweep's frequencies, they fix only the phase origin, the direction and the FSR,
as for the other label-free baselines. Given none (``fit(powers)``), the phase has a
documented convention: zero at the first reading of the fit, growing in the sense in which
the fit's readings move from the first to the last (their unwrapped phase, in record
order); frequency then follows from ``anchor_hz`` (the frequency of that first reading)
and ``fsr_hz``.
"""

from __future__ import annotations

import warnings

import numpy as np

from ...exceptions import CalibrationWarning, InputError
from ...validation import MIN_SAMPLES, check_dark, check_monitor, check_positive, check_powers
from ..files import fields
from ..files.document import state_array
from ..fitting.sweep import checked_port_names
from ..models.cone_fit import OFFSET_MODES, ConeFit, cone_phase_rad, fit_cone
from .baselines._labels import LabelLockedCalibrator

__all__ = ["ReferenceFreeCalibrator"]


class ReferenceFreeCalibrator(LabelLockedCalibrator):
    """Reference-free calibration: the cone from the readings alone.

    Parameters
    ----------
    fsr_hz : float
        Design FSR (Hz): refined within +-20 % by a sweep with frequencies; taken as the FSR
        of a fit without them.
    anchor_hz : None or float
        For a fit without frequencies: the frequency (Hz) of its first reading, which makes
        ``predict`` absolute within one FSR; None: phase only.
    offsets : {"none", "fit"}
        Detector offsets: zero (give known ones as ``dark_w``), or fitted from the readings
        (needs a source power that varies).

    Attributes
    ----------
    cone_ : ConeFit
        The fitted cone (W).
    direction_ : int
        +1 or -1: the sign relating the cone's raw phase to the phase returned.
    phase_origin_rad_ : float
        Raw phase (signed) at the phase origin (rad).
    fsr_hz_, center_hz_, span_hz_, calibration_rms_hz_ : see :class:`wavemeter.Calibrator`;
        for a fit without frequencies ``fsr_hz_`` is ``fsr_hz``, ``center_hz_`` is
        ``anchor_hz`` (or None), ``calibration_rms_hz_`` is NaN (not measured).

    Notes
    -----
    Origin and direction are conventions: with frequencies, phase 0 at ``center_hz_`` and
    growing with frequency; without, phase 0 at the first reading and growing along the
    record. Retrieval is invariant to source power (the cone's rays).

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> from wavemeter.model import wrap_to_period
    >>> cal = wm.ReferenceFreeCalibrator(fsr_hz=device.true_fsr_hz, anchor_hz=f_hz[0]).fit(powers)

    No frequencies were given: the FSR and the first reading's frequency make the readings
    absolute within one FSR:

    >>> error_hz = wrap_to_period(cal.predict(powers) - f_hz, device.true_fsr_hz)
    >>> print(f"{np.sqrt(np.mean(error_hz**2)) / 1e6:.0f} MHz RMS")
    14 MHz RMS
    """

    method = "reference_free"
    state_rules = fields.rule_table(
        {
            "cone.vertex_w": fields.OFFSET_RULE,
            "cone.basis": fields.FieldRule("the cone's basis", "", high=1.0, magnitude=True),
            "cone.frame": fields.FieldRule("the cone's frame", "1/W"),
            "cone.power_spread": fields.FieldRule(
                "the source power's relative spread", "", 0.0, 1.0
            ),
            "cone.frame_std_rad": fields.FieldRule(
                "the frame's phase distortion", "rad", 0.0, np.pi
            ),
        }
    )

    def __init__(self, fsr_hz: float = 50e9, anchor_hz=None, offsets: str = "none"):
        self.fsr_hz = fsr_hz
        self.anchor_hz = anchor_hz
        self.offsets = offsets

    def _check_params(self) -> None:
        super()._check_params()
        if self.anchor_hz is not None:
            check_positive("anchor_hz", self.anchor_hz)
        if self.offsets not in OFFSET_MODES:
            raise InputError(
                f"offsets must be one of {', '.join(map(repr, OFFSET_MODES))}, got "
                f"{self.offsets!r}",
                parameter="offsets",
            )

    # ------------------------------------------------------------------ fitting
    def fit(
        self,
        powers,
        frequency_hz=None,
        power_monitor_w=None,
        port_names=None,
        *,
        dark_w=None,
        temperature_k=None,
    ):
        """Learn the cone; with ``frequency_hz`` also the origin, direction and FSR.

        Parameters are those of :meth:`wavemeter.Calibrator.fit`; ``frequency_hz`` may be
        None (the readings in record order: the phase convention needs their order).

        Returns
        -------
        self
        """
        if frequency_hz is not None:
            return super().fit(
                powers,
                frequency_hz,
                power_monitor_w,
                port_names,
                dark_w=dark_w,
                temperature_k=temperature_k,
            )
        self._check_params()
        raw = check_powers(powers, min_samples=MIN_SAMPLES)
        monitor = check_monitor(power_monitor_w, raw.shape[0])
        dark = check_dark(dark_w, raw.shape[1])
        readings = raw if dark is None else raw - dark
        self.cone_ = fit_cone(readings, power=monitor, offsets=self.offsets)
        phase = np.unwrap(self._raw_phase(readings))
        net = float(phase[-1] - phase[0])
        self.direction_ = 1 if net >= 0 else -1
        self.phase_origin_rad_ = float(self.direction_ * phase[0])
        self.fsr_hz_ = float(self.fsr_hz)
        self.center_hz_ = None if self.anchor_hz is None else float(self.anchor_hz)
        half = 0.5 * self.fsr_hz_
        self.span_hz_ = (
            None if self.center_hz_ is None else (self.center_hz_ - half, self.center_hz_ + half)
        )
        self.n_ports_ = raw.shape[1]
        self.n_samples_ = raw.shape[0]
        self.port_names_ = checked_port_names(port_names, raw.shape[1])
        self.calibration_rms_hz_ = float("nan")
        self.dark_w_ = dark
        self.offset_w_ = np.zeros(raw.shape[1])
        total = readings.sum(axis=1)
        self.total_power_range_w_ = (float(total.min()), float(total.max()))
        self.diagnostics_ = {
            "labels": False,
            "phase_origin": "first reading of the fit",
            "direction": "growing from the first to the last reading of the fit",
            "net_phase_rad": abs(net),
            **self._method_diagnostics(),
        }
        if abs(net) < np.pi:
            warnings.warn(
                CalibrationWarning(
                    f"the fit's readings move by only {abs(net):.3g} rad from the first to the "
                    "last: the direction convention (growing along the record) rests on that",
                    cause="partial_span",
                    remedy="fit on a record whose phase moves by more than half a fringe, or "
                    "give frequency_hz",
                ),
                stacklevel=2,
            )
        return self

    def _learn(self, sweep):
        self.cone_ = fit_cone(sweep.powers_w, power=sweep.monitor_w, offsets=self.offsets)
        self._lock_to_labels(sweep.powers_w, sweep.frequency_hz)

    def _fit_sweep(self, sweep) -> list:
        notes = super()._fit_sweep(sweep)
        self.diagnostics_.update(self._method_diagnostics())
        return notes

    def _raw_phase(self, powers):
        return cone_phase_rad(self.cone_, powers)

    def _method_diagnostics(self) -> dict:
        return {
            "cone": {
                "power_spread": self.cone_.power_spread,
                "frame_std_rad": self.cone_.frame_std_rad,
                "offsets_w": self.cone_.vertex_w.tolist(),
            }
        }

    # ------------------------------------------------------------------ without labels
    def _labelled(self) -> bool:
        return bool(getattr(self, "diagnostics_", {}).get("labels", True))

    def _frequency_hz(self, readings, inputs):
        """Frequency (Hz) within ``center_hz_ +- fsr_hz_ / 2`` (see the base class).

        Raises
        ------
        InputError
            For a fit without frequencies and without ``anchor_hz``: phase only.
        """
        if self.center_hz_ is None:
            raise InputError(
                "this calibration was learned without frequencies and without anchor_hz: it "
                "gives phase only; set anchor_hz (the frequency of the first fit reading) and "
                "fit again",
                parameter="anchor_hz",
            )
        return super()._frequency_hz(readings, inputs)

    def _partial_span(self) -> bool:
        return self._labelled() and super()._partial_span()

    def summary(self):
        """The fit report (see the base class), for a fit with frequencies.

        Raises
        ------
        InputError
            For a fit without frequencies: it has no frequency scale to report; its phase
            convention and the cone's numbers are in ``diagnostics_``.
        """
        if not self._labelled():
            raise InputError(
                "a reference-free fit without frequencies has no calibration summary: its "
                "phase convention and the cone's numbers are in diagnostics_"
            )
        return super().summary()

    def save(self, path) -> None:
        """Write the calibration file (a fit with frequencies only).

        Raises
        ------
        InputError
            For a fit without frequencies (no calibration error was measured to save).
        """
        if not self._labelled():
            raise InputError(
                "a reference-free fit without frequencies is not saved: fit with frequency_hz "
                "(even a rough axis) to save a calibration file"
            )
        super().save(path)

    # ------------------------------------------------------------------ files
    def _state(self) -> dict:
        return {"cone": self.cone_.to_dict(), **self._lock_state()}

    def _set_state(self, state: dict) -> None:
        self.cone_ = ConeFit.from_dict(state.get("cone"), self.n_ports_, state_array)
        self._set_lock_state(state)

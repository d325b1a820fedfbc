"""What ``OFF_MODEL`` compares a reading's distance to the calibrated cone with.

By default the detector noise: a distance whose chi-square p-value is below
``OFF_MODEL_P_VALUE`` (:func:`~wavemeter.calibration.contract.flags.off_model_threshold`).
When the calibration sweep's own distances show a model error (more of them above the
noise's median than the noise allows at ``MODEL_ERROR_P_VALUE``), the sweep's distances
instead: the noise's distribution scaled to the sweep's median distance, at the same
p-value, so that ``OFF_MODEL`` says "unlike the calibration's readings".
:func:`off_model_basis` makes that judgement, :class:`OffModelBasis` keeps it (saved with
the calibration; a file without it keeps the detector-noise test) and
:class:`OffModelMixin` gives a calibrator with a cone map its threshold, state and summary
line. Theory: the docs' theory page on per-reading uncertainty and flags.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import NamedTuple

import numpy as np
from scipy import stats

from ...exceptions import InputError, shown
from ..files import fields
from .flags import OFF_MODEL_P_VALUE, off_model_threshold

__all__ = [
    "FALSE_ALARM_CONFIDENCE",
    "MODEL_ERROR_P_VALUE",
    "OffModelBasis",
    "OffModelMixin",
    "chi2_median",
    "off_model_basis",
]

#: the sweep's distances show a model error when this many or more of them lie above the
#: noise's median distance has a smaller probability than this under the noise alone
MODEL_ERROR_P_VALUE = 1e-6
#: confidence of the upper bound stated on the share of sweep readings beyond the threshold
FALSE_ALARM_CONFIDENCE = 0.95
#: key of the basis in a calibration file's state
STATE_KEY = "off_model"


@functools.lru_cache(maxsize=64)
def chi2_median(free: int, noise_dof: float) -> float:
    """The median of a cone distance under the calibrated noise: ``free F(free, noise_dof)``
    (``free = n - 2`` degrees of freedom, the noise estimated on ``noise_dof``)."""
    return free * float(stats.f.median(free, noise_dof))


class OffModelBasis(NamedTuple):
    """The calibration sweep's cone distances, as ``OFF_MODEL`` uses them (a named tuple:
    plain numbers, as learned attributes are).

    Attributes
    ----------
    readings : int
        Sweep readings whose distances were seen (every k-th of a long sweep).
    median : float
        Their median weighted squared distance to the cone (unitless).
    noise_median : float
        The median distance under the calibrated noise alone (:func:`chi2_median`).
    above : int
        Readings whose distance exceeds ``noise_median``.
    scale : float
        The ``OFF_MODEL`` threshold over the detector-noise one: ``median / noise_median``
        when the distances show a model error, else 1.
    beyond : int
        Sweep readings whose distance exceeds the threshold (the in-sample false alarms).
    """

    readings: int
    median: float
    noise_median: float
    above: int
    scale: float
    beyond: int

    @property
    def model_error(self) -> bool:
        """The sweep's distances exceed what the detector noise gives (the threshold is
        scaled to them)."""
        return self.scale > 1.0

    @property
    def p_value(self) -> float:
        """Probability under the noise alone that ``above`` or more of ``readings``
        distances exceed the noise's median (a one-sided sign test)."""
        return float(stats.binom.sf(self.above - 1, self.readings, 0.5))

    @property
    def beyond_bound(self) -> float:
        """Upper bound at ``FALSE_ALARM_CONFIDENCE`` on the share of readings like the
        sweep's beyond the threshold (Clopper-Pearson, from ``beyond`` of ``readings``)."""
        if self.beyond >= self.readings:
            return 1.0
        clear = self.readings - self.beyond
        return float(stats.beta.ppf(FALSE_ALARM_CONFIDENCE, self.beyond + 1, clear))

    def to_dict(self) -> dict:
        """The fields a calibration file keeps (``noise_median`` follows from the noise)."""
        return {
            "readings": self.readings,
            "median": self.median,
            "above": self.above,
            "scale": self.scale,
            "beyond": self.beyond,
        }

    def text(self, noise_threshold: float) -> str:
        """What the test is and on what basis, in a sentence (for ``summary()``)."""
        threshold = self.scale * noise_threshold
        found = (
            f"{self.above} of {self.readings} sweep readings above the noise's median distance "
            f"{self.noise_median:.3g}"
        )
        if not self.model_error:
            return (
                f"OFF_MODEL beyond cone distance {threshold:.4g}, the detector noise's at "
                f"p = {OFF_MODEL_P_VALUE:g} (no model error: {found}, sweep median "
                f"{self.median:.3g})"
            )
        return (
            f"OFF_MODEL beyond cone distance {threshold:.4g}, {self.scale:.4g}x the detector "
            f"noise's {noise_threshold:.4g}: a model error ({found}, {_p_text(self.p_value)}), "
            f"so the noise's distribution scaled to the sweep's median distance "
            f"{self.median:.4g}, at p = {OFF_MODEL_P_VALUE:g}; {self.beyond} of "
            f"{self.readings} sweep readings beyond it (a share below "
            f"{self.beyond_bound:.2g} at {FALSE_ALARM_CONFIDENCE:.0%} confidence)"
        )


def _p_text(p_value: float) -> str:
    """A p-value as text; one that underflows float64 as a bound."""
    return f"p = {p_value:.2g}" if p_value > 0 else "p < 1e-300"


def off_model_basis(distance, ports: int, noise_dof: float) -> OffModelBasis:
    """The ``OFF_MODEL`` basis of a calibration sweep from its readings' cone distances.

    Parameters
    ----------
    distance : ndarray, shape (N,)
        Each sweep reading's weighted squared distance to the fitted cone (maximum-
        likelihood phase and power, the calibrated per-port noise), unitless.
    ports : int
        Ports ``n`` (``n - 2`` degrees of freedom per distance).
    noise_dof : float
        Degrees of freedom of the calibrated noise.

    Returns
    -------
    OffModelBasis
        ``scale`` is ``median / noise_median`` when the one-sided sign test of the
        distances against the noise's median rejects at ``MODEL_ERROR_P_VALUE``, else 1.
        The median is robust: up to half the sweep may be outliers.
    """
    distance = np.asarray(distance, dtype=float)
    noise_median = chi2_median(ports - 2, noise_dof)
    median = float(np.median(distance))
    above = int(np.count_nonzero(distance > noise_median))
    p_value = float(stats.binom.sf(above - 1, distance.size, 0.5))
    scale = max(median / noise_median, 1.0) if p_value < MODEL_ERROR_P_VALUE else 1.0
    threshold = scale * off_model_threshold(ports, noise_dof)
    beyond = int(np.count_nonzero(distance > threshold))
    return OffModelBasis(distance.size, median, noise_median, above, scale, beyond)


def basis_from_state(state: dict, ports: int, noise_dof: float) -> OffModelBasis | None:
    """The basis a calibration file keeps, checked; None for a file without one (written
    by 0.7 and older), whose ``OFF_MODEL`` test stays the detector-noise one."""
    if state.get(STATE_KEY) is None:
        return None
    record = state[STATE_KEY]
    if not isinstance(record, dict):
        raise InputError(f"field {STATE_KEY!r} must be an object, got {type(record).__name__}")

    def number(key: str, minimum: float, integer: bool = False) -> float:
        value = record.get(key)
        try:
            real = isinstance(value, (int, float)) and not isinstance(value, bool)
            finite = real and math.isfinite(value)
        except OverflowError:  # an integer beyond float64
            finite = False
        if not finite:
            raise InputError(
                f"field '{STATE_KEY}.{key}' must be a finite number, got {shown(value)}"
            )
        if value < minimum or (integer and value != int(value)):
            kind = "an integer" if integer else "a number"
            raise InputError(
                f"field '{STATE_KEY}.{key}' must be {kind} >= {minimum:g}, got {shown(value)}"
            )
        return value

    readings = int(number("readings", 1, integer=True))
    above, beyond = (int(number(key, 0, integer=True)) for key in ("above", "beyond"))
    if max(above, beyond) > readings:
        raise InputError(
            f"fields '{STATE_KEY}.above' and '{STATE_KEY}.beyond' must not exceed "
            f"'{STATE_KEY}.readings' ({readings}), got {above} and {beyond}"
        )
    median, scale = float(number("median", 0.0)), float(number("scale", 1.0))
    return OffModelBasis(readings, median, chi2_median(ports - 2, noise_dof), above, scale, beyond)


#: the largest weighted squared cone distance a file may hold: a reading a million noise
#: standard deviations off the cone is no reading of a meter
MAX_DISTANCE = 1e12


def _count_rule(what: str) -> tuple:
    """A count of the sweep's readings: a whole number, at most the readings fitted."""
    return (
        fields.FieldRule(what, "", 0.0, integer=True),
        fields.FieldRule(what, "", high=1.0, scale="readings"),
    )


class OffModelMixin:
    """``OFF_MODEL``'s threshold, state and summary line for a calibrator with a cone map
    (module docstring). The class sets ``off_model_basis_`` when it fits
    (:meth:`_judge_distances`) and loads (:meth:`_set_off_model_state`)."""

    state_rules = fields.rule_table(
        {
            f"{STATE_KEY}.readings": _count_rule("the sweep readings the test saw"),
            f"{STATE_KEY}.above": _count_rule("the sweep readings above the noise's median"),
            f"{STATE_KEY}.beyond": _count_rule("the sweep readings beyond the threshold"),
            f"{STATE_KEY}.median": fields.FieldRule(
                "the sweep's median cone distance", "", 0.0, MAX_DISTANCE
            ),
            f"{STATE_KEY}.scale": fields.FieldRule("the threshold's scale", "", 1.0, MAX_DISTANCE),
        }
    )

    def _off_model_threshold(self) -> float:
        """The weighted squared distance beyond which a reading is ``OFF_MODEL``."""
        threshold = off_model_threshold(self.n_ports_, self.noise_dof_)
        basis = self.off_model_basis_
        return threshold if basis is None else basis.scale * threshold

    def _judge_distances(self, distance) -> None:
        """Set ``off_model_basis_`` from the sweep's cone distances (N,), at the fitted
        noise."""
        self.off_model_basis_ = off_model_basis(distance, self.n_ports_, self.noise_dof_)

    def _off_model_state(self) -> dict:
        """The basis for the calibration file (nothing for a file that had none)."""
        basis = self.off_model_basis_
        return {} if basis is None else {STATE_KEY: basis.to_dict()}

    def _set_off_model_state(self, state: dict) -> None:
        """The basis from a loaded state, after the noise (its degrees of freedom)."""
        self.off_model_basis_ = basis_from_state(state, self.n_ports_, self.noise_dof_)

    def summary(self):
        """The fit report, with what ``OFF_MODEL`` tests and on what basis."""
        report = super().summary()
        noise_threshold = off_model_threshold(self.n_ports_, self.noise_dof_)
        basis = self.off_model_basis_
        note = (
            f"OFF_MODEL beyond cone distance {noise_threshold:.4g}, the detector noise's at "
            f"p = {OFF_MODEL_P_VALUE:g} (a file without the sweep's distances)"
            if basis is None
            else basis.text(noise_threshold)
        )
        return dataclasses.replace(report, notes=(*report.notes, note))

"""What ``OFF_MODEL`` compares a reading's distance to the calibrated cone with.

By default the detector noise: a distance whose chi-square p-value is below
``OFF_MODEL_P_VALUE`` (:func:`~wavemeter.calibration.contract.flags.off_model_threshold`).
When the calibration sweep's own distances show a model error (more of them above the
noise's median than the noise allows at ``MODEL_ERROR_P_VALUE``), the residual the sweep's
readings share at their phase is learned
(:mod:`~wavemeter.calibration.contract.off_model_residual`) and subtracted from every
reading's before its distance is taken, and the noise's distribution is scaled to what
remains: to its median, or, where its tail is heavier than the noise's (at any of
``COVER_QUANTILES``), per phase to cover it. So ``OFF_MODEL`` says "unlike the
calibration's readings". :func:`off_model_basis` makes the
first judgement, :func:`with_residual` the second; :class:`OffModelBasis` keeps them (saved
with the calibration; a file without them keeps the test it had) and
:class:`OffModelMixin` gives a calibrator with a cone map its test, state and summary line.
Theory: the docs' diagnostics page (``OFF_MODEL`` when the model does not hold).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import NamedTuple

import numpy as np
from scipy import stats

from ...exceptions import InputError, shown
from .flags import OFF_MODEL_P_VALUE, off_model_threshold
from .off_model_residual import (
    CV_FOLDS,
    ResidualModel,
    learn_residual,
    learn_spread,
    residual_from_record,
)
from .off_model_rules import OFF_MODEL_STATE_RULES

__all__ = [
    "COVER_QUANTILES",
    "FALSE_ALARM_CONFIDENCE",
    "MAX_RESIDUAL_READINGS",
    "MODEL_ERROR_P_VALUE",
    "OffModelBasis",
    "OffModelMixin",
    "chi2_median",
    "exceeds_scaled_noise",
    "off_model_basis",
    "with_residual",
]

#: the sweep's distances show a model error when this many or more of them lie above the
#: noise's median distance has a smaller probability than this under the noise alone
MODEL_ERROR_P_VALUE = 1e-6
#: confidence of the upper bound stated on the share of sweep readings beyond the threshold
FALSE_ALARM_CONFIDENCE = 0.95
#: key of the basis in a calibration file's state
STATE_KEY = "off_model"
#: the quantiles at which the remaining distances are compared with the noise's (and which
#: the scaled distribution covers): fewer than 1 % of the sweep may be outliers
COVER_QUANTILES = (0.5, 0.75, 0.9, 0.95, 0.98, 0.99)
#: most sweep readings the residual is learned from (every k-th of a longer sweep)
MAX_RESIDUAL_READINGS = 2**14


@functools.lru_cache(maxsize=64)
def chi2_median(free: int, noise_dof: float) -> float:
    """The median of a cone distance under the calibrated noise: ``free F(free, noise_dof)``
    (``free = n - 2`` degrees of freedom, the noise estimated on ``noise_dof``)."""
    return free * float(stats.f.median(free, noise_dof))


def noise_quantiles(free: int, noise_dof: float) -> np.ndarray:
    """The cone distance's ``COVER_QUANTILES`` under the calibrated noise."""
    return free * stats.f.ppf(COVER_QUANTILES, free, noise_dof)


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
        Without ``residual``: the ``OFF_MODEL`` threshold over the detector-noise one,
        ``median / noise_median`` when the distances show a model error, else 1. With it:
        the factor of the noise's distribution that fits the remaining distances
        (:func:`with_residual`; times their spread at the phase, where learned).
    beyond : int
        Sweep readings whose tested distance exceeds the threshold (the in-sample false
        alarms; cross-validated with ``residual``).
    residual : ResidualModel or None
        What the sweep's readings share off the cone, subtracted before the test (files
        written before it was learned have none).
    """

    readings: int
    median: float
    noise_median: float
    above: int
    scale: float
    beyond: int
    residual: ResidualModel | None = None

    @property
    def model_error(self) -> bool:
        """The sweep's distances exceed what the detector noise gives."""
        return self.scale > 1.0 or self.residual is not None

    @property
    def p_value(self) -> float:
        """Probability under the noise alone that ``above`` or more of ``readings``
        distances exceed the noise's median (a one-sided sign test)."""
        return float(stats.binom.sf(self.above - 1, self.readings, 0.5))

    @property
    def tested(self) -> int:
        """Sweep readings whose tested distance is counted in ``beyond``."""
        return self.readings if self.residual is None else self.residual.readings

    @property
    def beyond_bound(self) -> float:
        """Upper bound at ``FALSE_ALARM_CONFIDENCE`` on the share of readings like the
        sweep's beyond the threshold (Clopper-Pearson, from ``beyond`` of ``tested``)."""
        if self.beyond >= self.tested:
            return 1.0
        clear = self.tested - self.beyond
        return float(stats.beta.ppf(FALSE_ALARM_CONFIDENCE, self.beyond + 1, clear))

    def factor(self, phase_rad) -> np.ndarray | float:
        """The ``OFF_MODEL`` threshold over the detector-noise one, at each reading's
        phase (rad): ``scale``, times ``exp(spread(t))`` with a learned spread."""
        if self.residual is None or not self.residual.spread_coefficients:
            return self.scale
        return self.scale * np.exp(self.residual.spread(phase_rad))

    def to_dict(self) -> dict:
        """The fields a calibration file keeps (``noise_median`` follows from the noise)."""
        record = {
            "readings": self.readings,
            "median": self.median,
            "above": self.above,
            "scale": self.scale,
            "beyond": self.beyond,
        }
        if self.residual is not None:
            record["residual"] = self.residual.to_dict()
        return record

    def text(self, noise_threshold: float) -> str:
        """What the test is and on what basis, in a sentence (for ``summary()``)."""
        found = (
            f"{self.above} of {self.readings} sweep readings above the noise's median distance "
            f"{self.noise_median:.3g}"
        )
        false_alarms = (
            f"{self.beyond} of {self.tested} sweep readings beyond it (a share below "
            f"{self.beyond_bound:.2g} at {FALSE_ALARM_CONFIDENCE:.0%} confidence)"
        )
        if not self.model_error:
            return (
                f"OFF_MODEL beyond cone distance {noise_threshold:.4g}, the detector noise's "
                f"at p = {OFF_MODEL_P_VALUE:g} (no model error: {found}, sweep median "
                f"{self.median:.3g})"
            )
        if self.residual is None:
            return (
                f"OFF_MODEL beyond cone distance {self.scale * noise_threshold:.4g}, "
                f"{self.scale:.4g}x the detector noise's {noise_threshold:.4g}: a model error "
                f"({found}, {_p_text(self.p_value)}), so the noise's distribution scaled to "
                f"the sweep's median distance {self.median:.4g}, at p = {OFF_MODEL_P_VALUE:g}; "
                + false_alarms
            )
        return (
            f"OFF_MODEL: a model error ({found}, {_p_text(self.p_value)}, median "
            f"{self.median:.4g}), so {_residual_text(self.residual)} is subtracted from each "
            f"reading's residual first (cross-validated median distance then "
            f"{self.residual.median:.4g}); {self._threshold_text(noise_threshold)}; " + false_alarms
        )

    def _threshold_text(self, noise_threshold: float) -> str:
        if self.residual.spread_harmonics is None:
            return (
                f"what remains is like the detector noise scaled to its median: OFF_MODEL "
                f"beyond cone distance {self.scale * noise_threshold:.4g}, {self.scale:.4g}x "
                f"the detector noise's, at p = {OFF_MODEL_P_VALUE:g}"
            )
        phase = np.linspace(-np.pi, np.pi, 721)
        factor = self.factor(phase)
        return (
            f"what remains has a heavier tail than the noise, so the noise's distribution "
            f"scaled to cover it "
            f"at its quantiles {', '.join(f'{q:g}' for q in COVER_QUANTILES)} at each phase "
            f"(its level {self.residual.spread_harmonics} harmonics in the phase): OFF_MODEL "
            f"beyond cone distance {factor.min() * noise_threshold:.4g} to "
            f"{factor.max() * noise_threshold:.4g} ({factor.min():.4g}x to "
            f"{factor.max():.4g}x the detector noise's), at p = {OFF_MODEL_P_VALUE:g}"
        )


def _residual_text(residual: ResidualModel) -> str:
    """The learned residual's form in words."""
    if residual.harmonics < 0:
        return "nothing (no residual shared by the sweep's readings improved on none)"
    shape = f"a Fourier series of {residual.harmonics} harmonics in the phase"
    if residual.power_degree:
        shape += f" times a polynomial of degree {residual.power_degree} in the source power"
    return (
        f"the residual the sweep's readings share ({shape}, chosen by {CV_FOLDS}-fold "
        f"cross-validation on {residual.readings} readings)"
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
        distances against the noise's median rejects at ``MODEL_ERROR_P_VALUE``, else 1
        (:func:`with_residual` then learns what the readings share). The median is
        robust: up to half the sweep may be outliers.
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


def exceeds_scaled_noise(distance, scale: float, ports: int, noise_dof: float) -> bool:
    """Whether distances (N,) exceed the noise's distribution scaled by ``scale`` at any of
    ``COVER_QUANTILES``: more of them above its quantile ``q`` than it allows (binomial,
    ``1 - q``) at ``MODEL_ERROR_P_VALUE / len(COVER_QUANTILES)`` (so at most that in all)."""
    quantiles = scale * noise_quantiles(ports - 2, noise_dof)
    counts = np.count_nonzero(np.asarray(distance)[:, None] > quantiles, axis=0)
    p_values = stats.binom.sf(counts - 1, len(distance), 1.0 - np.array(COVER_QUANTILES))
    return bool(np.min(p_values) < MODEL_ERROR_P_VALUE / len(COVER_QUANTILES))


def with_residual(
    basis: OffModelBasis, readings, maps, phase_rad, noise_std_w, noise_dof: float
) -> OffModelBasis:
    """A basis that shows a model error, with the residual its sweep's readings share.

    Parameters
    ----------
    basis : OffModelBasis
        From :func:`off_model_basis` of the same readings.
    readings : ndarray, shape (N, n)
        Offset-corrected sweep readings (W); every k-th of more than
        ``MAX_RESIDUAL_READINGS``.
    maps : ndarray, shape (n, 3) or (N, n, 3)
        The calibrated map, or each reading's.
    phase_rad : ndarray, shape (N,)
        Each reading's retrieved phase (rad), by the calibration's own retrieval.
    noise_std_w : ndarray, shape (n,)
        The calibrated port noise (W).
    noise_dof : float

    Returns
    -------
    OffModelBasis
        With ``residual`` (:func:`~wavemeter.calibration.contract.off_model_residual.
        learn_residual`). ``scale``: the cross-validated remaining distances' median over
        the noise's, where the noise's distribution so scaled holds them at every
        ``COVER_QUANTILES`` point (:func:`exceeds_scaled_noise`); else their spread over
        the phase is learned and ``scale`` is the least that covers them, normalised by
        it, at every such point. ``beyond`` counts them beyond the threshold.
    """
    step = max(1, math.ceil(len(phase_rad) / MAX_RESIDUAL_READINGS))
    readings, phase = readings[::step], np.asarray(phase_rad)[::step]
    if maps.ndim == 3:
        maps = maps[::step]
    ports = readings.shape[1]
    residual, remaining = learn_residual(readings, maps, phase, noise_std_w)
    noise_median = chi2_median(ports - 2, noise_dof)
    # the least positive scale keeps a threshold for remaining distances of zero
    scale = max(float(np.median(remaining)) / noise_median, np.finfo(float).tiny)
    if exceeds_scaled_noise(remaining, scale, ports, noise_dof):
        residual = residual._replace(
            spread_coefficients=learn_spread(phase, remaining, noise_median)
        )
        level = remaining / np.exp(residual.spread(phase))
        covered = np.quantile(level, COVER_QUANTILES) / noise_quantiles(ports - 2, noise_dof)
        scale = float(np.max(covered))
    found = basis._replace(scale=scale, residual=residual)
    threshold = found.factor(phase) * off_model_threshold(ports, noise_dof)
    return found._replace(beyond=int(np.count_nonzero(remaining > threshold)))


def basis_from_state(state: dict, ports: int, noise_dof: float) -> OffModelBasis | None:
    """The basis a calibration file keeps, checked; None for a file without one (written
    by 0.7 and older), whose ``OFF_MODEL`` test stays the detector-noise one. A record
    without ``residual`` (written before it was learned) keeps its median-scaled test."""
    if state.get(STATE_KEY) is None:
        return None
    record = state[STATE_KEY]
    if not isinstance(record, dict):
        raise InputError(f"field {STATE_KEY!r} must be an object, got {type(record).__name__}")

    def number(key: str, minimum: float, integer: bool = False, open_minimum=False) -> float:
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
        below = value <= minimum if open_minimum else value < minimum
        if below or (integer and value != int(value)):
            kind = "an integer" if integer else "a number"
            relation = ">" if open_minimum else ">="
            raise InputError(
                f"field '{STATE_KEY}.{key}' must be {kind} {relation} {minimum:g}, "
                f"got {shown(value)}"
            )
        return value

    readings = int(number("readings", 1, integer=True))
    above, beyond = (int(number(key, 0, integer=True)) for key in ("above", "beyond"))
    residual = None
    if record.get("residual") is not None:
        residual = residual_from_record(record["residual"], ports, f"{STATE_KEY}.residual")
    tested = readings if residual is None else residual.readings
    if above > readings or beyond > tested:
        raise InputError(
            f"fields '{STATE_KEY}.above' and '{STATE_KEY}.beyond' must not exceed the "
            f"readings counted ({readings} and {tested}), got {above} and {beyond}"
        )
    median = float(number("median", 0.0))
    scale = (
        float(number("scale", 1.0))
        if residual is None
        else float(number("scale", 0.0, open_minimum=True))
    )
    noise_median = chi2_median(ports - 2, noise_dof)
    return OffModelBasis(readings, median, noise_median, above, scale, beyond, residual)


class OffModelMixin:
    """``OFF_MODEL``'s test, state and summary line for a calibrator with a cone map
    (module docstring). The class sets ``off_model_basis_`` when it fits
    (:meth:`_judge_distances`) and loads (:meth:`_set_off_model_state`)."""

    #: the record's rules, merged with the class's own (``declared_rules``)
    state_rules = OFF_MODEL_STATE_RULES

    def _off_model_threshold(self) -> float:
        """The weighted squared distance beyond which a reading is ``OFF_MODEL``, without a
        learned residual (:meth:`_off_model_learned`)."""
        threshold = off_model_threshold(self.n_ports_, self.noise_dof_)
        basis = self.off_model_basis_
        return threshold if basis is None else basis.scale * threshold

    def _off_model_learned(self) -> bool:
        """Whether the test subtracts a learned residual (:meth:`_off_model_remaining`)
        instead of comparing the cone distance with :meth:`_off_model_threshold`."""
        basis = self.off_model_basis_
        return basis is not None and basis.residual is not None

    def _off_model_remaining(self, readings, maps, phase_rad) -> np.ndarray:
        """``OFF_MODEL`` (N,) of offset-corrected readings at their retrieved phase (N,),
        under the map (n, 3) or each reading's (N, n, 3), with the learned residual."""
        basis = self.off_model_basis_
        noise = self.port_noise_std_w_
        remaining = basis.residual.distance(readings, maps, phase_rad, noise)
        threshold = off_model_threshold(self.n_ports_, self.noise_dof_)
        return remaining > basis.factor(phase_rad) * threshold

    def _judge_distances(self, distance, readings, maps, phase_rad) -> None:
        """Set ``off_model_basis_`` from the sweep's cone distances (N,), at the fitted
        noise; with a model error, learn the residual its readings (N, n), offset-corrected,
        share at their retrieved phase (N,) under ``maps`` (:func:`with_residual`)."""
        basis = off_model_basis(distance, self.n_ports_, self.noise_dof_)
        if basis.model_error:
            noise = self.port_noise_std_w_
            basis = with_residual(basis, readings, maps, phase_rad, noise, self.noise_dof_)
        self.off_model_basis_ = basis

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

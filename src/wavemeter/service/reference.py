"""Keeping the meter true with a reference laser: checked, logged re-anchors of the calibration.

A :class:`ReferenceKeeper` watches the readings of one channel that sees a laser of known
frequency. Every ``interval_s``, or as soon as the readings since the last attempt stray
from the known frequency by more than ``threshold_hz``, it reads the latest ``window_s`` of
the reference's port readings with the *base* calibration (the one loaded, so corrections
never pile up), fits the meter's offset as a line in time (over the latest part of the
window that is one) and extrapolates it to the middle of the coming interval (a meter that
drifts is corrected where it will be, not where it was), and judges the window
(:func:`~.reference_checks.check_window`; the allowance is ``max_drift_hz_per_s`` times the
time since the last accepted anchor). If it passes, the base is re-anchored with its own
``reanchor`` so that it reads the reference true at that time (the fitted readings given
in bins along the fitted drift, each bin a line), and the readings are read again to
confirm it. A refusal (a check, an error or a warning of ``reanchor`` other than its
scatter test's, which the window's check makes at ``p_false``, a failed confirmation)
keeps the anchor in force and raises the alarm until
the next accepted re-anchor. Every attempt is a :class:`ReanchorEvent` with the offset left
before and after. The keeper knows no sockets or clocks (times come with the readings).
"""

from __future__ import annotations

import math
import warnings
from collections import deque
from dataclasses import asdict, dataclass

import numpy as np
from scipy import stats

from ..exceptions import InputError, WavemeterError
from .reference_checks import MIN_FIT_READINGS, P_FALSE, check_window

#: bins of the window in which the fitted drift moves by at most this fraction of the
#: per-reading noise are each re-anchored as one line (a spread within a bin of at most 0.15
#: of the noise: 2 % more variance)
_BIN_DRIFT = 0.5
#: the cause of the calibration's warning that a line's readings scatter beyond its noise
_SCATTER_CAUSE = "reference_scatter"

__all__ = [
    "ReferenceKeeper",
    "ReanchorEvent",
    "MIN_READINGS",
    "DEFAULT_INTERVAL_S",
    "DEFAULT_WINDOW_S",
    "DEFAULT_MAX_DRIFT_HZ_PER_S",
]

#: fewest readings in a window that is judged
MIN_READINGS = MIN_FIT_READINGS
#: seconds between attempts, and seconds of readings each fits, by default
DEFAULT_INTERVAL_S = 0.05
DEFAULT_WINDOW_S = 1.0
#: the fastest drift of the meter the check allows by default (Hz/s): a silicon-nitride chip
#: (2.6 GHz/K) warming by 0.1 K/s
DEFAULT_MAX_DRIFT_HZ_PER_S = 2.6e8
#: times closer than this (s) are equal (readings every 1 / rate add up in floating point)
_TIME_TOLERANCE_S = 1e-9
#: events kept in memory
_KEPT_EVENTS = 200


@dataclass(frozen=True)
class ReanchorEvent:
    """One attempt at re-anchoring.

    Attributes
    ----------
    time_s : float
        The time of the window's last reading (s, the readings' clock).
    accepted : bool
        Whether the calibration was re-anchored.
    reason : str
        Why it was refused ("" when accepted).
    trigger : str
        ``"interval"`` or ``"threshold"``.
    readings : int
        Readings in the window.
    before_hz : float
        The meter's offset at the anchor's time that the anchor in force leaves (Hz).
    after_hz : float
        What the new anchor leaves (Hz; NaN when refused).
    correction_hz : float
        The change of the anchor (Hz; NaN when refused).
    offset_std_hz : float
        The standard error of the fitted offset (Hz).
    drift_hz_per_s : float
        The meter's drift the window shows (Hz/s).
    phase_shift_rad : float
        The bias phase of the new anchor relative to the base calibration (NaN when refused).
    scatter_ratio, worst_z, allowance_hz : float
        What the check saw (see :class:`~.reference_checks.WindowCheck`).
    """

    time_s: float
    accepted: bool
    reason: str
    trigger: str
    readings: int
    before_hz: float
    after_hz: float
    correction_hz: float
    offset_std_hz: float
    drift_hz_per_s: float
    phase_shift_rad: float
    scatter_ratio: float
    worst_z: float
    allowance_hz: float

    def describe(self) -> dict:
        return asdict(self)


class ReferenceKeeper:
    """Re-anchors a calibration to readings of a reference laser, after checking them.

    Parameters
    ----------
    calibration : BaseCalibrator
        The base calibration (it must declare the ``"reanchor"`` capability).
    frequency_hz : float
        The reference laser's frequency (Hz), inside the calibration's span.
    interval_s : float
        Seconds between attempts, > 0.
    window_s : float
        Seconds of readings an attempt fits, > 0.
    threshold_hz : float, optional
        Attempt at once when the readings since the last attempt are off by more than this
        on average (Hz); None: only every ``interval_s``.
    max_drift_hz_per_s : float
        The fastest the meter drifts (Hz/s), > 0: the allowance of the check.
    p_false : float
        The probability that each check refuses good readings.

    Attributes
    ----------
    calibration : BaseCalibrator
        The calibration in force (the base, or its latest re-anchored copy).
    events : deque of ReanchorEvent
        The latest attempts.
    accepted, refused : int
        Attempts so far.
    alarm : str or None
        The reason of the latest refusal while no re-anchor has been accepted since.
    """

    def __init__(
        self,
        calibration,
        frequency_hz: float,
        *,
        interval_s: float = DEFAULT_INTERVAL_S,
        window_s: float = DEFAULT_WINDOW_S,
        threshold_hz: float | None = None,
        max_drift_hz_per_s: float = DEFAULT_MAX_DRIFT_HZ_PER_S,
        p_false: float = P_FALSE,
    ):
        if "reanchor" not in calibration.capabilities:
            raise InputError(
                f"a {calibration.method_label} calibration cannot be re-anchored, so it cannot "
                "follow a reference laser",
                parameter="reference",
            )
        low, high = calibration.span_hz_
        ok = isinstance(frequency_hz, int | float) and not isinstance(frequency_hz, bool)
        if not (ok and low <= frequency_hz <= high):
            raise InputError(
                f"reference frequency {frequency_hz!r} Hz: expected inside the calibration's "
                f"span, {low / 1e12:.6f} to {high / 1e12:.6f} THz",
                parameter="reference",
            )
        for name, value in (
            ("interval_s", interval_s),
            ("window_s", window_s),
            ("max_drift_hz_per_s", max_drift_hz_per_s),
        ):
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise InputError(f"{name} {value!r}: expected a number > 0", parameter=name)
        if threshold_hz is not None and not (
            isinstance(threshold_hz, int | float) and threshold_hz > 0
        ):
            raise InputError(
                f"threshold_hz {threshold_hz!r}: expected a number > 0", parameter="threshold_hz"
            )
        self.base = calibration
        self.calibration = calibration
        self.frequency_hz = float(frequency_hz)
        self.interval_s = float(interval_s)
        self.window_s = float(window_s)
        self.threshold_hz = threshold_hz
        self.max_drift_hz_per_s = float(max_drift_hz_per_s)
        self.p_false = p_false
        self.events: deque[ReanchorEvent] = deque(maxlen=_KEPT_EVENTS)
        self.accepted = 0
        self.refused = 0
        self.alarm: str | None = None
        self._inputs = [
            name for name in ("temperature_k", "coarse_hz") if name in calibration.requires
        ]
        self._chunks: deque = deque()  # (time_s, powers, frequency, flags, inputs)
        self._attempt_s = None
        self._spacing_s = self.interval_s
        self._anchored_hz = 0.0  # the offset (base terms) the anchor in force corrects
        self._anchored_s = None  # the time it is for

    def rebase(self, calibration) -> None:
        """A new base calibration (a reload): in force, uncorrected, until the next anchor."""
        self.base = calibration
        self.calibration = calibration
        self._inputs = [
            name for name in ("temperature_k", "coarse_hz") if name in calibration.requires
        ]
        self._anchored_hz = 0.0
        self._chunks.clear()

    def add(self, time_s, powers, frequency_hz, flags, **inputs) -> ReanchorEvent | None:
        """Take readings of the reference; attempt a re-anchor when one is due.

        Parameters
        ----------
        time_s : ndarray, shape (N,)
            When each was taken (s), increasing.
        powers : ndarray, shape (N, ports)
            Their port readings (the calibration's unit).
        frequency_hz : ndarray, shape (N,)
            Their readings with the calibration in force (Hz).
        flags : ndarray of int, shape (N,)
            Their flag bits.
        **inputs : ndarray, shape (N,)
            ``temperature_k`` / ``coarse_hz`` where the calibration needs them.

        Returns
        -------
        ReanchorEvent or None
            The attempt made now (accepted or refused), or None.
        """
        times = np.asarray(time_s, dtype=float)
        if not len(times):
            return None
        now = float(times[-1])
        if self._attempt_s is None:
            self._attempt_s = self._anchored_s = float(times[0])
        kept = {name: np.asarray(inputs[name], dtype=float) for name in self._inputs}
        self._chunks.append((times, np.asarray(powers), np.asarray(frequency_hz), flags, kept))
        while self._chunks and self._chunks[0][0][-1] <= now - self.window_s:
            self._chunks.popleft()
        since = now - self._attempt_s
        if since >= self.interval_s - _TIME_TOLERANCE_S:
            return self._attempt(now, "interval")
        if self.threshold_hz is not None:
            last = self._attempt_s
            recent = [c[2][c[0] > last] for c in self._chunks if c[0][-1] > last]
            recent = np.concatenate(recent) if recent else np.empty(0)
            if len(recent) >= MIN_READINGS:
                if abs(np.nanmean(recent) - self.frequency_hz) > self.threshold_hz:
                    return self._attempt(now, "threshold")
        return None

    def _window(self, now: float):
        parts = list(zip(*self._chunks, strict=True))
        times = np.concatenate(parts[0])
        chosen = times > now - self.window_s
        powers = np.concatenate(parts[1])[chosen]
        flags = np.concatenate(parts[3])[chosen]
        inputs = {
            name: np.concatenate([i[name] for i in parts[4]])[chosen] for name in self._inputs
        }
        return times[chosen], powers, flags, inputs

    def _attempt(self, now: float, trigger: str) -> ReanchorEvent | None:
        times, powers, flags, inputs = self._window(now)
        if len(times) < MIN_READINGS:
            return None
        if self._attempt_s is not None and now > self._attempt_s:
            # the time between attempts as it is (readings come in batches): the anchor is
            # for the middle of the coming one
            self._spacing_s += 0.2 * (now - self._attempt_s - self._spacing_s)
        self._attempt_s = now
        at_s = now + 0.5 * self._spacing_s
        base = self.base.readout(powers, **inputs)
        error = np.asarray(base.frequency_hz) - self.frequency_hz
        check = check_window(
            times,
            error,
            base.frequency_std_hz,
            np.asarray(flags) | np.asarray(base.flags, dtype=np.int64),
            at_s=at_s,
            anchored_hz=self._anchored_hz,
            allowance_hz=self.max_drift_hz_per_s * (at_s - self._anchored_s),
            max_drift_hz_per_s=self.max_drift_hz_per_s,
            p_false=self.p_false,
        )
        reason, anchored, shift = check.reason, math.nan, math.nan
        if check.ok:
            # the readings the line was fitted to, each as a reading of what the base
            # shifted by -offset reads there: known + drift (t - at_s), in bins short enough
            # for the drift to stay well inside the noise (each bin one line to reanchor)
            fitted = slice(len(times) - check.fitted, None)
            noise_hz = float(np.median(base.frequency_std_hz))
            offsets = self._offsets_hz(times[fitted], check.drift_hz_per_s, noise_hz, at_s)
            used = {name: value[fitted] for name, value in inputs.items()}
            new, reason = self._reanchor(powers[fitted], offsets, used)
            if new is not None:
                read = new.readout(powers[fitted], **used).frequency_hz
                anchored = check.offset_hz + float(np.mean(read - self.frequency_hz - offsets))
                limit = check.offset_std_hz * float(stats.norm.isf(self.p_false / 2))
                if not abs(anchored - check.offset_hz) <= limit:
                    left = check.offset_hz - anchored
                    reason = (
                        f"the re-anchored calibration leaves {left / 1e6:+.4g} MHz of the "
                        f"offset (at most {limit / 1e6:.4g} MHz expected)"
                    )
                else:
                    shift = float(new.diagnostics_["reanchor"]["phase_shift_rad"])
        before = check.offset_hz - self._anchored_hz
        if not reason:
            self.calibration = new
            self.accepted += 1
            self.alarm = None
            correction = anchored - self._anchored_hz
            self._anchored_hz, self._anchored_s = anchored, at_s
        else:
            self.refused += 1
            self.alarm = reason
            anchored = correction = math.nan
        event = ReanchorEvent(
            time_s=now,
            accepted=not reason,
            reason=reason,
            trigger=trigger,
            readings=len(times),
            before_hz=before,
            after_hz=check.offset_hz - anchored,
            correction_hz=correction,
            offset_std_hz=check.offset_std_hz,
            drift_hz_per_s=check.drift_hz_per_s,
            phase_shift_rad=shift,
            scatter_ratio=check.scatter_ratio,
            worst_z=check.worst_z,
            allowance_hz=check.allowance_hz,
        )
        self.events.append(event)
        return event

    @staticmethod
    def _offsets_hz(times, drift_hz_per_s: float, noise_hz: float, at_s: float) -> np.ndarray:
        """Per reading, what the re-anchored calibration should read off the known
        frequency: the fitted drift since ``at_s`` (Hz), constant over bins in which the
        drift moves by at most ``_BIN_DRIFT`` of the noise ``noise_hz``."""
        span = float(times[-1] - times[0])
        width = _BIN_DRIFT * noise_hz / abs(drift_hz_per_s) if drift_hz_per_s else math.inf
        if not width < span:
            return np.full(len(times), drift_hz_per_s * (float(np.mean(times)) - at_s))
        _, bins = np.unique(((times - times[0]) // width).astype(int), return_inverse=True)
        centers = np.bincount(bins, weights=times) / np.bincount(bins)
        return drift_hz_per_s * (centers[bins] - at_s)

    def _reanchor(self, powers, offsets_hz, inputs):
        """The base re-anchored on these readings (each of the known frequency plus its
        offset), or None and the reason it was not."""
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                new = self.base.reanchor(powers, self.frequency_hz + offsets_hz, **inputs)
            except WavemeterError as exc:
                return None, f"the calibration refused to re-anchor: {exc}"
        # the reference's scatter is judged by check_window, at p_false and blind to the
        # drift; the calibration's own scatter test (at p = 1e-3 per attempt, many a minute)
        # would refuse good windows every few minutes
        doubts = [
            w
            for w in caught
            if issubclass(w.category, UserWarning)
            and getattr(w.message, "cause", None) != _SCATTER_CAUSE
        ]
        if doubts:
            return None, f"the calibration doubts the reference: {doubts[0].message}"
        return new, ""

    def describe(self) -> dict:
        """The keeper's settings, counts, alarm and latest event, JSON-ready."""
        latest = self.events[-1].describe() if self.events else None
        return {
            "frequency_hz": self.frequency_hz,
            "interval_s": self.interval_s,
            "window_s": self.window_s,
            "threshold_hz": self.threshold_hz,
            "max_drift_hz_per_s": self.max_drift_hz_per_s,
            "accepted": self.accepted,
            "refused": self.refused,
            "alarm": self.alarm,
            "offset_hz": self._anchored_hz,
            "latest": latest,
        }

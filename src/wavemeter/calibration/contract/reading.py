"""Reading with a fitted calibration: one rule for every calibrator, one reading at a time.

:class:`ReadingMixin` gives every calibrator ``predict``, ``phase``, ``frequency_std_hz``,
``crlb_hz``, ``flags``, ``readout`` and ``score`` with the same keywords, on top of a few
methods a calibrator writes (``_phase``, and where it differs ``_phase_rad``,
``_frequency_hz``, ``_frequency_std``, ``_crlb``, ``_model_flags``, ``_coverage``,
``_readout``). The rule they share: a reading the calibration cannot read (NaN or inf,
no light, a per-reading input that is not a number, a coarse frequency where it has no
map) gets NaN and the :class:`~wavemeter.calibration.contract.flags.ReadingFlag` bits that
say why, and costs no other reading; ``errors="raise"`` refuses such readings instead.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ...exceptions import InputError
from ...model.cone import phase_to_frequency_hz, wrap_to_period
from ...validation import (
    check_choice,
    check_coarse_inside,
    check_fitted,
    check_frequency,
    check_per_reading,
    check_powers,
    reading_array,
)
from .flags import SPAN_MARGIN_STD, ReadingFlag, power_flags
from .records import ReadingInputs, Readout

__all__ = ["ERRORS", "ReadingMixin", "Prepared"]

#: what a reading method does with readings it cannot read: NaN and flags, or an error
ERRORS = ("coerce", "raise")


@dataclass(frozen=True)
class Prepared:
    """Readings checked for shape, less their offsets, with what each one allows.

    Attributes
    ----------
    readings : ndarray, shape (N, n)
        As given (float64).
    corrected : ndarray, shape (N, n)
        Less the dark readings and fitted offsets.
    inputs : ReadingInputs
        The per-reading inputs, one value per reading where given.
    flags : ndarray of int64, shape (N,)
        ``INVALID``, ``POWER_RANGE`` and, for a coarse value with no map, ``OUTSIDE_SPAN``.
    readable : ndarray of bool, shape (N,)
        Readings the calibration can read: finite, lit, their inputs finite, a map for
        their coarse value (a dim reading is read, and flagged ``INVALID``).
    """

    readings: np.ndarray
    corrected: np.ndarray
    inputs: ReadingInputs
    flags: np.ndarray
    readable: np.ndarray


class ReadingMixin:
    """The reading API every calibrator answers (module docstring)."""

    # ------------------------------------------------------------------ preparation
    def _reading_inputs(
        self, coarse_hz, temperature_k, samples: int, *, finite: bool = True
    ) -> ReadingInputs:
        """The per-reading inputs, each None or ``samples`` values (finite unless
        ``finite`` is False); raise when one named in ``requires`` is None."""
        given = {"coarse_hz": coarse_hz, "temperature_k": temperature_k}
        missing = [name for name in sorted(self.requires) if given[name] is None]
        if missing:
            raise InputError(
                f"{type(self).__name__} needs {' and '.join(missing)} for each reading "
                f"({self._requirement_reason()}); got None",
                parameter=missing[0],
            )
        return ReadingInputs(
            **{
                name: None
                if value is None
                else check_per_reading(name, value, samples, finite=finite)
                for name, value in given.items()
            }
        )

    def _requirement_reason(self) -> str:
        return "declared in its requires"

    def _prepared(self, powers, coarse_hz, temperature_k, errors: str) -> Prepared:
        """The readings and inputs checked; per reading, what it allows (:class:`Prepared`).

        With ``errors="raise"`` a reading that cannot be read raises :class:`InputError`
        naming it (its row, zero-based) and what to do.
        """
        check_fitted(self)
        check_choice("errors", errors, ERRORS)
        strict = errors == "raise"
        if strict:
            readings = check_powers(powers, ports=self.n_ports_)
        else:
            readings = reading_array(powers, ports=self.n_ports_)
        samples = readings.shape[0]
        inputs = self._reading_inputs(coarse_hz, temperature_k, samples, finite=strict)
        offset = self._reading_offset_w()
        corrected = readings - offset if offset.any() else readings
        flags, readable = self._light(readings, corrected)
        unknown = ~inputs.finite(samples)
        flags[unknown] |= ReadingFlag.INVALID
        readable &= ~unknown
        coverage = self._coverage(inputs)
        if coverage is not None:
            inside, outside_text = coverage
            if strict:
                check_coarse_inside(inputs.coarse_hz, inside, outside_text, parameter="coarse_hz")
            outside = ~inside & readable
            flags[outside] |= ReadingFlag.OUTSIDE_SPAN
            readable &= ~outside
        return Prepared(readings, corrected, inputs, flags, readable)

    def _computed(self, prepared: Prepared, compute: Callable, *args) -> np.ndarray:
        """``compute(readings, inputs, *args)`` of the readable readings; NaN for the others."""
        rows = prepared.readable
        if rows.all():
            return compute(prepared.corrected, prepared.inputs, *args)
        result = np.full(rows.size, np.nan)
        if rows.any():
            result[rows] = compute(prepared.corrected[rows], prepared.inputs.rows(rows), *args)
        return result

    def _coverage(self, inputs: ReadingInputs) -> tuple[np.ndarray, str] | None:
        """Where the calibration has a map for the coarse values: ``(inside, text)`` with
        ``inside`` per reading and ``text`` what the others are (for the error of
        ``errors="raise"``); None when every coarse value is covered (or none is needed)."""
        return None

    def _reading_offset_w(self) -> np.ndarray:
        """What every reading carries besides the light (W, per port): dark plus fitted offsets."""
        total = self.offset_w_
        dark = self.dark_w_
        return total if dark is None else total + dark

    def _corrected(self, powers) -> np.ndarray:
        """Readings validated strictly (finite, lit), less their offsets."""
        check_fitted(self)
        readings = check_powers(powers, ports=self.n_ports_)
        offset = self._reading_offset_w()
        # most calibrations have none: no copy of the readings then
        return readings - offset if offset.any() else readings

    def _light(self, readings: np.ndarray, corrected: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``INVALID`` (NaN, inf, too little light) and ``POWER_RANGE`` bits of readings
        (N, n), raw and less their offsets
        (:func:`~wavemeter.calibration.contract.flags.power_flags`), and which of them can
        be read at all (finite, with a positive total power)."""
        with np.errstate(invalid="ignore"):
            flags = power_flags(
                corrected.sum(axis=1), self.total_power_range_w_, self._offsets_known()
            )
            lit = np.isfinite(readings).all(axis=1) & (readings.sum(axis=1) > 0)
        flags[~lit] |= ReadingFlag.INVALID
        return flags, lit

    def _light_flags(self, readings: np.ndarray, corrected: np.ndarray) -> np.ndarray:
        """The bits of :meth:`_light`."""
        return self._light(readings, corrected)[0]

    def _offsets_known(self) -> bool:
        """Dark readings were given, or offsets fitted (a monitored power that varied)."""
        return self.dark_w_ is not None or bool(np.any(self.offset_w_))

    # ------------------------------------------------------------------ the public methods
    def predict(self, powers, *, coarse_hz=None, temperature_k=None, errors="coerce"):
        """Source frequency (Hz) of each reading.

        A single-FSR calibration returns the frequency within ``center_hz_ +- fsr_hz_/2``;
        one that reads a band (from a coarse value, or a cascade) the absolute frequency.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
            Port readings, in the unit of the calibration sweep.
        coarse_hz, temperature_k : None, float or array_like, shape (N,)
            Per-reading inputs (Hz, K); required when named in ``requires``.
        errors : {"coerce", "raise"}
            A reading that cannot be read gets NaN (its ``flags`` say why), or raises.

        Returns
        -------
        ndarray, shape (N,), Hz

        Raises
        ------
        InputError
            For readings of the wrong shape or port count, a missing required input, and
            with ``errors="raise"`` a reading that cannot be read.
        """
        prepared = self._prepared(powers, coarse_hz, temperature_k, errors)
        return self._computed(prepared, self._frequency_hz)

    def phase(self, powers, *, coarse_hz=None, temperature_k=None, errors="coerce"):
        """Interferometer phase (rad) in (-pi, pi], zero at ``center_hz_`` (a set: at each
        window's centre; a wide band: the model phase of the frequency found).

        Parameters and errors as for :meth:`predict`.

        Returns
        -------
        ndarray, shape (N,), rad
        """
        prepared = self._prepared(powers, coarse_hz, temperature_k, errors)
        return self._computed(prepared, self._phase_rad)

    def frequency_std_hz(
        self,
        powers,
        *,
        coarse_hz=None,
        temperature_k=None,
        include_calibration=True,
        errors="coerce",
    ):
        """Standard deviation (Hz) of each reading's frequency estimate, where
        ``"frequency_std"`` is a capability.

        ``(estimate - true) / frequency_std_hz`` has unit standard deviation for in-model
        readings.

        Parameters
        ----------
        powers, coarse_hz, temperature_k, errors
            As for :meth:`predict`.
        include_calibration : bool
            Add the calibration's own uncertainty (default) or give the reading noise only.

        Returns
        -------
        ndarray, shape (N,), Hz

        Raises
        ------
        InputError
            For a class that does not provide it; as for :meth:`predict`.
        """
        self._require_capability("frequency_std", "gives no per-reading uncertainty")
        prepared = self._prepared(powers, coarse_hz, temperature_k, errors)
        return self._computed(prepared, self._frequency_std, include_calibration)

    def crlb_hz(
        self, powers, *, coarse_hz=None, temperature_k=None, frequency_hz=None, errors="coerce"
    ):
        """Cramer-Rao bound (Hz) of each reading under the calibrated model and port noise,
        where ``"crlb"`` is a capability.

        At the reading's own source power, and at the frequency the calibration reads or,
        given ``frequency_hz`` (e.g. the truth in an evaluation), at the phase the model
        gives that frequency.

        Returns
        -------
        ndarray, shape (N,), Hz
        """
        self._require_capability("crlb", "gives no Cramer-Rao bound")
        prepared = self._prepared(powers, coarse_hz, temperature_k, errors)
        truth = None
        if frequency_hz is not None:
            truth = check_frequency(
                np.broadcast_to(frequency_hz, prepared.readings.shape[:1]),
                prepared.readings.shape[0],
            )
        rows = prepared.readable
        result = np.full(rows.size, np.nan)
        if rows.any():
            result[rows] = self._crlb(
                prepared.corrected[rows],
                prepared.inputs.rows(rows),
                None if truth is None else truth[rows],
            )
        return result

    def flags(self, powers, *, coarse_hz=None, temperature_k=None):
        """Quality bit mask per reading (:class:`~wavemeter.calibration.ReadingFlag`).

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
            Port readings, in the unit of the calibration sweep; NaN and dark ones too.
        coarse_hz, temperature_k : None, float or array_like, shape (N,)
            Per-reading inputs; required when named in ``requires``.

        Returns
        -------
        ndarray of int64, shape (N,)
            0 for a reading with nothing to report; ``flags & ReadingFlag.OFF_MODEL`` etc.
        """
        prepared = self._prepared(powers, coarse_hz, temperature_k, "coerce")
        flags = prepared.flags.copy()
        rows = prepared.readable & ((flags & ReadingFlag.INVALID) == 0)
        if rows.any():
            flags[rows] |= self._model_flags(prepared.corrected[rows], prepared.inputs.rows(rows))
        return flags

    def readout(self, powers, *, coarse_hz=None, temperature_k=None, errors="coerce") -> Readout:
        """Frequency, its uncertainty, the quality flags and the extra outputs, in one pass.

        What ``predict``, ``frequency_std_hz`` (NaN where not a capability), ``flags`` and
        the extra outputs the class declares in ``reading_outputs`` give.

        Parameters and errors as for :meth:`predict`.

        Returns
        -------
        Readout
        """
        prepared = self._prepared(powers, coarse_hz, temperature_k, errors)
        samples = prepared.readable.size
        frequency, std, phase = (np.full(samples, np.nan) for _ in range(3))
        extras = {name: np.full(samples, np.nan) for name in self.reading_outputs}
        flags = prepared.flags.copy()
        rows = prepared.readable
        state = {}
        if rows.any():
            found = self._readout(prepared.corrected[rows], prepared.inputs.rows(rows))
            frequency[rows], std[rows] = found.frequency_hz, found.frequency_std_hz
            phase[rows] = found.phase_rad
            # a dim reading is read, but its flags say only that it is no reading to trust
            flags[rows] |= np.where(flags[rows] & ReadingFlag.INVALID, 0, found.flags)
            for name, values in extras.items():
                values[rows] = found.extras[name]
            state = found.state
        return Readout(frequency, std, flags, extras, phase, state)

    def readout_notes(self, states) -> list:
        """Warnings about the readings as a whole, from the ``state`` of every
        :class:`Readout` of them (the blocks of a file); none for most calibrations."""
        return []

    def score(self, powers, frequency_hz, *, coarse_hz=None, temperature_k=None) -> float:
        """Negative RMS frequency error (Hz) on readings of known frequency (higher is better).

        Errors are taken modulo the calibrated FSR for a single-FSR calibrator (it measures
        frequency modulo its FSR), absolutely for one that reports absolute frequency (from
        a coarse input, or ``absolute_frequency``).
        """
        predicted = self.predict(
            powers, coarse_hz=coarse_hz, temperature_k=temperature_k, errors="raise"
        )
        truth = check_frequency(frequency_hz, predicted.shape[0])
        error = predicted - truth
        if not (self.requires & {"coarse_hz"} or self.absolute_frequency):
            error = wrap_to_period(error, self.fsr_hz_)
        return -float(np.sqrt(np.mean(error**2)))

    def _require_capability(self, capability: str, missing: str) -> None:
        if capability not in self.capabilities:
            raise InputError(
                f"{type(self).__name__} ({type(self).method!r}) {missing}; calibrators that "
                f"do list {capability!r} in their capabilities"
            )

    # ------------------------------------------------------------------ what a calibrator writes
    def _phase(self, readings: np.ndarray) -> np.ndarray:
        """Phase (rad, zero at ``center_hz_``) of offset-corrected readings (N, n)."""
        raise NotImplementedError

    def _phase_rad(self, readings: np.ndarray, inputs: ReadingInputs) -> np.ndarray:
        """:meth:`phase` of readable, offset-corrected readings (N, n): ``_phase`` here."""
        return self._phase(readings)

    def _frequency_hz(self, readings: np.ndarray, inputs: ReadingInputs) -> np.ndarray:
        """:meth:`predict` of readable, offset-corrected readings: the phase over the FSR."""
        return phase_to_frequency_hz(
            self._phase_rad(readings, inputs), self.center_hz_, self.fsr_hz_
        )

    def _frequency_std(self, readings, inputs: ReadingInputs, include_calibration: bool):
        """:meth:`frequency_std_hz` of readable, offset-corrected readings."""
        raise NotImplementedError

    def _crlb(self, readings, inputs: ReadingInputs, frequency_hz) -> np.ndarray:
        """:meth:`crlb_hz` of readable, offset-corrected readings (at ``frequency_hz`` (N,)
        when given)."""
        raise NotImplementedError

    def _model_flags(self, readings: np.ndarray, inputs: ReadingInputs) -> np.ndarray:
        """``OUTSIDE_SPAN`` and ``OFF_MODEL`` bits of readable, offset-corrected readings.

        ``OUTSIDE_SPAN``: for a calibration over less than one FSR, a frequency outside the
        sweep by more than ``SPAN_MARGIN_STD`` of its standard deviations (none where the
        class gives none). ``OFF_MODEL``: where :meth:`_off_model` has a test.
        """
        flags = np.zeros(readings.shape[0], dtype=np.int64)
        if self._partial_span():
            frequency = self._frequency_hz(readings, inputs)
            margin = 0.0
            if "frequency_std" in self.capabilities:
                margin = self._frequency_std(readings, inputs, True)
            flags |= self._span_flags(frequency, margin)
        off_model = self._off_model(readings, inputs)
        if off_model is not None:
            flags[off_model] |= ReadingFlag.OFF_MODEL
        return flags

    def _off_model(self, readings: np.ndarray, inputs: ReadingInputs) -> np.ndarray | None:
        """Boolean per reading: improbably far from the calibrated model (None: no test)."""
        return None

    def _readout(self, readings: np.ndarray, inputs: ReadingInputs) -> Readout:
        """:meth:`readout` of readable, offset-corrected readings: frequency, its standard
        deviation (NaN where not a capability), the model's flag bits and the phase."""
        frequency = self._frequency_hz(readings, inputs)
        if "frequency_std" in self.capabilities:
            std = self._frequency_std(readings, inputs, True)
        else:
            std = np.full(frequency.shape, np.nan)
        flags = self._model_flags(readings, inputs)
        return Readout(frequency, std, flags, {}, self._phase_rad(readings, inputs))

    # ------------------------------------------------------------------ the span rule
    def _partial_span(self) -> bool:
        """The sweep covered less than one FSR: frequencies outside it are flagged."""
        low, high = self.span_hz_
        samples = self.n_samples_
        return (high - low) * samples / max(samples - 1, 1) < self.fsr_hz_

    def _span_flags(self, frequency_hz: np.ndarray, margin_std_hz) -> np.ndarray:
        """``OUTSIDE_SPAN`` bits of frequencies (Hz) outside the sweep by more than
        ``SPAN_MARGIN_STD`` times ``margin_std_hz`` (Hz, one or one per frequency)."""
        low, high = self.span_hz_
        margin = SPAN_MARGIN_STD * margin_std_hz
        outside = (frequency_hz < low - margin) | (frequency_hz > high + margin)
        return np.where(outside, np.int64(ReadingFlag.OUTSIDE_SPAN), np.int64(0))

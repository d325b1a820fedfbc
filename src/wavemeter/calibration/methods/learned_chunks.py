"""A long sweep fitted on the binned moments of every reading, checked on every k-th.

:class:`LargeSweepMixin` gives the learned calibrator :meth:`~LargeSweepMixin.fit_chunks`
(a sweep read in chunks, in memory bounded by the chunk) and the fit of a sweep given
whole beyond ``diagnostic_samples`` readings: delay, map, noise and covariance from one
pass of binned moments over every reading (:mod:`~wavemeter.calibration.models.moments`),
the checks and diagnostics on every k-th reading
(:mod:`~wavemeter.calibration.models.subsample`).
"""

from __future__ import annotations

from ...blas import one_blas_thread
from ...exceptions import InputError
from ...validation import MIN_SAMPLES
from ..fitting.steps import check_ports, guard_design_fsr, issue
from ..fitting.sweep import Sweep, checked_port_names, value_range
from ..models.learned_fit import (
    AFFINE_MIN_POWER_SPREAD,
    MAX_MOMENT_BYTES,
    gram_objects,
    moment_fit,
    port_noise_from_squares,
    relative_map,
)
from ..models.moments import BLOCK_ROWS, FringeMoments, largest_search_delay_s
from ..models.subsample import CheckedChunks, SweepSample

__all__ = ["LargeSweepMixin"]


class LargeSweepMixin:
    """The learned fit of a sweep too long for every check (module docstring); the class
    provides the fit's context class (``_context``) and its steps (``_start_fit``,
    ``_take_fit``, ``_set_covariance``, ``_judged``, ``_fit_every_reading``)."""

    def fit_chunks(self, chunks, port_names=None, *, dark_w=None):
        """Learn the calibration from a sweep read in chunks, in memory bounded by the chunk.

        One pass: every chunk is checked, binned into the sweep's moments and sampled
        (every k-th reading), then dropped. A sweep of up to ``diagnostic_samples``
        readings is then fitted as :meth:`fit` fits it (the sample holds every reading: the
        same numbers, bit for bit); a longer one is fitted on the moments and diagnosed on
        the sample, as :meth:`fit` does with a long sweep given whole (the same numbers to
        rounding; see the class notes).

        Parameters
        ----------
        chunks : iterable of (frequency_hz, powers, power_monitor_w)
            In sweep order: ``frequency_hz`` (m,) Hz, ``powers`` (m, n) port readings (W or
            any unit linear in power), ``power_monitor_w`` (m,) or None, the same ``n`` and
            either always or never a monitor; any sizes, empty ones too.
        port_names : None or sequence of str, length n
            Names of the port columns, kept in the calibration file.
        dark_w : None or array_like, shape (n,)
            Per-port dark readings (W), subtracted from every reading, in fit and predict.

        Returns
        -------
        self

        Raises
        ------
        InputError
            As :meth:`fit`; a chunk's message names it and its first reading (zero-based).
            When the sweep spans so many fringes that its moments would take more than
            ``MAX_MOMENT_BYTES`` (the design FSR is then checked first), or for a class
            without the ``"fit_chunks"`` capability.
        EdgeMinimumError
            As :meth:`fit`.

        Warns
        -----
        CalibrationWarning
            As :meth:`fit`.
        """
        self._check_params()
        if "fit_chunks" not in self.capabilities:
            raise InputError(
                f"{type(self).__name__} fits every reading of its sweep at once (no "
                "'fit_chunks' in its capabilities): give the whole sweep to fit, not chunks "
                "to fit_chunks"
            )
        checked = CheckedChunks(chunks, dark_w)
        with one_blas_thread():
            moments, sample = self._accumulate(checked)
            if sample.samples < MIN_SAMPLES:
                raise InputError(f"need at least {MIN_SAMPLES} samples, got {sample.samples}")
            names = checked_port_names(port_names, sample.powers_w.shape[1])
            sweep = Sweep(
                sample.powers_w, sample.frequency_hz, sample.monitor_w, names, checked.dark
            )
            if sample.stride == 1:  # every reading kept: the sweep is in memory
                notes = self._fit_every_reading(sweep)
            else:
                notes = self._fit_sampled(moments, sample, sweep, None)
        issue(notes)
        return self

    def _fit_on_moments(self, sweep: Sweep) -> list:
        """A sweep too long for every check: the fit on the moments of every reading, the
        checks on every k-th (:meth:`_fit_sampled`)."""
        rows = range(0, sweep.samples, BLOCK_ROWS)
        blocks = (sweep.rows(slice(start, start + BLOCK_ROWS)) for start in rows)
        moments, sample = self._accumulate(
            (block.frequency_hz, block.powers_w, block.monitor_w) for block in blocks
        )
        return self._fit_sampled(moments, sample, sweep, value_range(sweep.temperature_k))

    def _accumulate(self, chunks) -> tuple[FringeMoments | None, SweepSample]:
        """One pass over checked, dark-subtracted chunks: their moments (None once they
        outgrow ``MAX_MOMENT_BYTES``) and the sample."""
        moments = FringeMoments(largest_search_delay_s(self.fsr_hz, self.fsr_tolerance), 0.0)
        sample = SweepSample(self.diagnostic_samples)
        for frequency, powers, monitor in chunks:
            sample.add(frequency, powers, monitor)
            if moments is not None:
                moments.add(frequency, powers, monitor)
                if moments.nbytes > MAX_MOMENT_BYTES:
                    moments = None  # the check of the design FSR (on the sample) speaks first
        return moments, sample

    def _fit_sampled(self, moments, sample: SweepSample, sweep: Sweep, temperature_range) -> list:
        """Fit on the moments of every reading, check and diagnose on the sample; the
        warnings, not yet issued."""
        checked = Sweep(
            sample.powers_w,
            sample.frequency_hz,
            sample.monitor_w,
            sweep.port_names,
            sweep.dark_w,
            monitor_mean_w=None if sample.monitor_w is None else sample.monitor_mean_w,
        )
        ctx = self._context(checked, temperature_range_k=temperature_range)
        guard_design_fsr(
            ctx,
            self.fsr_hz,
            self.fsr_tolerance,
            step_hz=sample.median_step_hz(),
            span_hz=sample.span_hz,
        )
        if moments is None:
            raise InputError(
                f"the sweep spans {sample.span_hz / self.fsr_hz:.4g} FSRs of "
                f"{self.fsr_hz / 1e9:.6g} GHz: its binned moments would take more than "
                f"{MAX_MOMENT_BYTES >> 20} MiB; one map does not hold over so many FSRs: "
                "calibrate it per FSR (CalibrationSet) or with WidebandCalibrator",
                parameter="fsr_hz",
            )
        self._start_fit(
            (sample.low_hz, sample.high_hz), sweep.port_names, sample.samples, sweep.dark_w
        )
        check_ports(ctx, self.center_hz_, range(checked.ports), self.fringe_ports_needed)
        ctx.affine = (
            sample.monitor_w is not None
            and sweep.dark_w is None
            and sample.monitor_relative_std >= AFFINE_MIN_POWER_SPREAD
        )
        moments.center_hz = self.center_hz_
        fit = moment_fit(
            moments,
            fsr_hz=self.fsr_hz,
            fsr_tolerance=self.fsr_tolerance,
            search=self.search,
            xtol=self.xtol,
            affine=ctx.affine,
        )
        noise, self.noise_dof_ = port_noise_from_squares(
            moments.port_residual_w2(fit.delay_s, fit.map_), moments.samples, fit.map_.shape[1], 1
        )
        mean_scale = moments.mean_scale
        self._take_fit(fit, relative_map(fit.map_, mean_scale), noise, sample.largest_w)
        ctx.gram = gram_objects(moments, fit.delay_s, ctx.affine, mean_scale)
        self._set_covariance(ctx)
        offsets = float(self.offset_w_.sum())
        low, high = sample.total_range_w
        self.total_power_range_w_ = (low - offsets, high - offsets)
        return self._judged(ctx)

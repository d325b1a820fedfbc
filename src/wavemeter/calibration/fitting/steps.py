"""The steps every fit shares, in the order a fit takes them.

1. :func:`~wavemeter.calibration.fitting.sweep.checked_sweep`: the inputs validated;
2. :func:`guard_design_fsr`: the design FSR against the sweep's own fringes, before any
   delay grid is built (:mod:`~wavemeter.calibration.checks.fsr_guard`);
3. :func:`check_ports`: every port's fringe (:mod:`~wavemeter.calibration.checks.port_health`);
4. the method learns;
5. :func:`cone_misfit_report` (or the method's own): the sweep against the model
   (:mod:`~wavemeter.calibration.checks.misfit`);
6. :func:`diagnostics_record`: what the checks found, and every warning, in order.

:class:`SweepFitMixin` is that sequence for a calibrator that learns in one step
(``_learn``); the learned, thermal and wide-band calibrators write theirs out, with these
same steps.
"""

from __future__ import annotations

import warnings

import numpy as np

from ...blas import one_blas_thread
from ...model.cone import wrap_to_period
from ..checks.fsr_guard import check_design_fsr
from ..checks.misfit import MisfitReport, misfit_report
from ..checks.port_health import check_port_health, port_health
from ..contract.records import ReadingInputs
from ..models.delay_search import DEFAULT_FSR_TOLERANCE
from ..models.learned_fit import AFFINE_MIN_POWER_SPREAD
from ..models.linear_map import fit_map, object_vectors
from .reference import ReferenceCellMixin, cell_inputs
from .sweep import FitContext, Sweep, checked_powers, checked_sweep

__all__ = [
    "AFFINE_MIN_POWER_SPREAD",
    "SweepFitMixin",
    "check_ports",
    "cone_misfit_report",
    "diagnostics_record",
    "fits_offsets",
    "guard_design_fsr",
    "issue",
    "rms",
]


def rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def fits_offsets(sweep: Sweep) -> bool:
    """Per-port offsets are fitted: the monitored power varied (relative spread at least
    ``AFFINE_MIN_POWER_SPREAD``) and no dark readings were given."""
    return (
        sweep.scale is not None
        and sweep.dark_w is None
        and float(np.std(sweep.scale)) >= AFFINE_MIN_POWER_SPREAD
    )


def guard_design_fsr(
    ctx: FitContext, fsr_hz: float, fsr_tolerance: float, rows=None, **whole_sweep
) -> None:
    """Step 2: the design FSR checked against the sweep (or the readings ``rows`` of it;
    ``step_hz`` and ``span_hz`` of the whole sweep when the sweep is a sample of it); the
    sweep's own FSR and delay go into ``ctx``."""
    sweep = ctx.sweep if rows is None else ctx.sweep.rows(rows)
    ctx.estimate = check_design_fsr(
        sweep.powers_w,
        sweep.frequency_hz,
        fsr_hz=float(fsr_hz),
        fsr_tolerance=fsr_tolerance,
        scale=sweep.scale,
        **whole_sweep,
    )
    ctx.delay_s = 1.0 / float(fsr_hz) if ctx.estimate is None else ctx.estimate.delay_s


def check_ports(
    ctx: FitContext, center_hz: float, ports_read, needed: int, phase_rad=None, objects=None
):
    """Step 3: every port's fringe at the sweep's delay (or at the model phase
    ``phase_rad``, or under the method's design columns ``objects``); raises when fewer
    than ``needed`` of ``ports_read`` carry one, warns about the bad ones."""
    sweep = ctx.sweep
    ctx.health = port_health(
        sweep.powers_w,
        sweep.frequency_hz,
        center_hz,
        ctx.delay_s,
        sweep.port_names,
        sweep.scale,
        phase_rad=phase_rad,
        objects=objects,
    )
    ctx.notes += check_port_health(
        [ctx.health[k] for k in ports_read], sweep.samples, needed=needed
    )


def cone_misfit_report(
    ctx: FitContext, center_hz: float, method: str | None = None
) -> MisfitReport:
    """Step 5 for a method without a cone map of its own: the sweep against the cone model
    with the least-squares map at the sweep's own delay (the data are tested against the
    model, not against a method's approximations). The checks of the pseudo-inverse
    retrieval concern the learned calibrator only and are left out; ``method`` the
    calibration's, which no remedy suggests."""
    sweep = ctx.sweep
    objects = object_vectors(sweep.frequency_hz, center_hz, ctx.delay_s, sweep.scale)
    return misfit_report(
        sweep.powers_w,
        sweep.frequency_hz,
        center_hz,
        ctx.delay_s,
        fit_map(objects, sweep.powers_w),
        scale=sweep.scale,
        dark_given=sweep.dark_w is not None,
        weighted_retrieval=True,
        axis_bandwidth_per_reading=sweep.axis_bandwidth_per_reading,
        method=method,
    )


def diagnostics_record(
    ctx: FitContext, misfit: MisfitReport, *, method: dict | None = None, notes=()
) -> tuple[dict, list]:
    """Step 6: ``diagnostics_`` from what the checks found, and every warning in order
    (the ports', the misfit report's, then the method's ``notes``)."""
    every = ctx.notes + list(misfit.warnings) + list(notes)
    record = {
        "fsr_estimate_hz": None if ctx.estimate is None else ctx.estimate.fsr_hz,
        "ports": [port.to_dict() for port in ctx.health],
        "fit": misfit.to_dict(),
        "temperature_range_k": ctx.temperature_range_k,
        "diagnostic_samples": int(ctx.sweep.samples),
        **(method or {}),
        "warnings": [note.record() for note in every],
    }
    return record, every


def issue(notes, stacklevel: int = 3) -> None:
    """Emit a fit's warnings, in order, from the caller of ``fit``."""
    for note in notes:
        warnings.warn(note, stacklevel=stacklevel)


class SweepFitMixin(ReferenceCellMixin):
    """``fit`` as the steps above, for a calibrator that learns in one step.

    The class writes ``_learn(sweep)``: set the learned attributes (``fsr_hz_`` and its
    own) from the validated sweep, whose layout ``_start_fit`` has already recorded.
    ``fit`` takes a reference cell (:mod:`~wavemeter.calibration.fitting.reference`): the
    ``"reference_cell"`` capability, declared here by default (a class that declares its
    own capabilities lists it where it offers it).

    Examples
    --------
    ``fit`` as the checked steps every fit shares: the sweep checked, the design FSR
    compared with the sweep's fringes, every port's fringe judged, then the class's own
    ``_learn``, then the residual tested against the cone model. A calibrator that learns
    in one step writes only ``_learn`` (and ``_phase``):

    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> from wavemeter.calibration import BaseCalibrator, SweepFitMixin
    >>> from wavemeter.model import cone_vectors, delay_phase_rad
    >>> class KnownDelayCalibrator(SweepFitMixin, BaseCalibrator):  # the map at a known FSR
    ...     def __init__(self, fsr_hz=50e9):
    ...         self.fsr_hz = fsr_hz
    ...     def _learn(self, sweep):
    ...         phase_rad = delay_phase_rad(sweep.frequency_hz, self.center_hz_, 1 / self.fsr_hz)
    ...         objects = cone_vectors(phase_rad, 1.0 if sweep.scale is None else sweep.scale)
    ...         self.map_ = np.linalg.lstsq(objects, sweep.powers_w, rcond=None)[0].T
    ...         self.fsr_hz_ = float(self.fsr_hz)
    ...     def _phase(self, readings):
    ...         objects = readings @ np.linalg.pinv(self.map_).T
    ...         return np.arctan2(objects[:, 1], objects[:, 0])
    >>> try:  # the fit's checks come with the mixin
    ...     KnownDelayCalibrator(fsr_hz=50).fit(powers, f_hz)
    ... except wm.InputError as error:
    ...     print(error.parameter)
    fsr_hz
    >>> cal = KnownDelayCalibrator(fsr_hz=device.true_fsr_hz).fit(powers, f_hz)
    >>> sorted(cal.diagnostics_)[:3]
    ['diagnostic_samples', 'fit', 'fsr_estimate_hz']
    """

    capabilities = frozenset({"power_monitor", "reference_cell"})

    def fit(
        self,
        powers,
        frequency_hz,
        power_monitor_w=None,
        port_names=None,
        *,
        dark_w=None,
        temperature_k=None,
        reference_transmission=None,
        reference_lines=None,
        band_hz=None,
        reference_pressure_pa=None,
        reference_pressure_std_pa=0.0,
        axis_error_hz=None,
    ):
        """Learn the calibration from a sweep of known frequencies (or of a reference cell).

        Parameters
        ----------
        powers : array_like, shape (N, n)
            Port readings (W, or any unit linear in power), ``N >= 4``, ``n >= 3``.
        frequency_hz : None or array_like, shape (N,)
            Known source frequency of each reading (Hz): the laser's recorded axis. None
            (with a reference cell and ``band_hz``): self-calibrate, no axis at all.
        power_monitor_w : None or array_like, shape (N,)
            Source-power monitor reading (W, or any unit linear in power).
        port_names : None or sequence of str, length n
            Names of the port columns, kept in the calibration file.
        dark_w : None or array_like, shape (n,)
            Per-port dark readings (W, the unit of ``powers``), subtracted from every
            reading, in fit and in predict.
        temperature_k : None, float or array_like, shape (N,)
            Chip temperature of each reading (K): required by a calibrator that names
            ``temperature_k`` in ``requires`` (the thermal one); its range is kept in
            ``diagnostics_["temperature_range_k"]`` by every calibrator.
        reference_transmission : None or array_like, shape (N,)
            A reference gas cell's channel recorded beside the ports, one reading per
            sweep reading: the sweep's axis is corrected with its lines (or made from them
            without ``frequency_hz``) and the calibration fitted on it; ``axis_correction_``
            and ``uncertainty_budget_`` record how. Needs ``"reference_cell"`` among the
            capabilities (:mod:`wavemeter.calibration.fitting.reference`).
        reference_lines : None or ReferenceLines
            The cell's line table (``wm.ReferenceLines.read_csv``).
        band_hz : None or (float, float)
            The band the sweep covers (Hz): the lines are identified among the table's in
            it; required without ``frequency_hz``.
        reference_pressure_pa, reference_pressure_std_pa : None or float
            The cell's pressure and its standard uncertainty (Pa), for a table of
            zero-pressure centres with pressure shifts.
        axis_error_hz : None or float
            Bound on the recorded axis's error (Hz): below a quarter of the line spacing
            each line is the nearest table line; None: the lines are identified by the
            pattern of their spacings.

        Returns
        -------
        self

        Raises
        ------
        InputError
            For readings or settings that are wrong; with ``parameter="fsr_hz"`` when the
            design FSR cannot be right for this sweep (the message gives the sweep's own
            FSR); naming the ports when too few carry a fringe; naming ``temperature_k``
            when the class requires it and it is missing; naming ``reference_lines`` when
            the cell's lines cannot be identified uniquely (the reason).
        EdgeMinimumError
            When the best delay lies outside the FSR bracket searched.

        Warns
        -----
        CalibrationWarning
            ``"dead_port"`` for a port without a fringe; a misfit cause
            (:data:`wavemeter.calibration.checks.misfit_causes.CAUSES`) when the sweep departs
            from the model. The evidence is kept in ``diagnostics_``.
        """
        self._check_params()
        required = type(self).__name__ if "temperature_k" in self.requires else None
        raw = checked_powers(powers)
        reference = {
            "reference_transmission": reference_transmission,
            "reference_lines": reference_lines,
            "band_hz": band_hz,
            "reference_pressure_pa": reference_pressure_pa,
            "reference_pressure_std_pa": reference_pressure_std_pa,
            "axis_error_hz": axis_error_hz,
        }

        def fit_on(axis_hz, axis_bandwidth_per_reading=0.0):
            sweep = checked_sweep(
                raw,
                axis_hz,
                power_monitor_w,
                port_names,
                dark_w=dark_w,
                temperature_k=temperature_k,
                temperature_required_by=required,
                axis_bandwidth_per_reading=axis_bandwidth_per_reading,
            )
            return self._fit_sweep(sweep)

        with one_blas_thread():
            notes = self._fit_with_cell(
                raw,
                frequency_hz,
                reference,
                fit_on,
                fsr_tolerance=self._fsr_tolerance(),
                dark_w=dark_w,
                inputs=cell_inputs(raw.shape[0], temperature_k, required),
            )
        issue(notes)
        return self

    def _fit_sweep(self, sweep: Sweep) -> list:
        """The steps on a validated sweep; the warnings, not yet issued."""
        ctx = FitContext(sweep)
        guard_design_fsr(ctx, self.fsr_hz, self._fsr_tolerance())
        self._start_fit(sweep.span_hz, sweep.port_names, sweep.samples, sweep.dark_w)
        check_ports(ctx, self.center_hz_, self._ports_read(sweep.ports), self.fringe_ports_needed)
        self._learn(sweep)
        self._take_power_range(sweep.powers_w)
        error = self._frequency_hz(sweep.powers_w - self.offset_w_, ReadingInputs())
        self.calibration_rms_hz_ = rms(wrap_to_period(error - sweep.frequency_hz, self.fsr_hz_))
        self.diagnostics_, notes = diagnostics_record(
            ctx, cone_misfit_report(ctx, self.center_hz_, self.method)
        )
        return notes

    def _fsr_tolerance(self) -> float:
        """Relative half width of the FSR bracket the fit searches around ``fsr_hz``."""
        return DEFAULT_FSR_TOLERANCE

    def _ports_read(self, ports: int) -> list[int]:
        """Indices of the ports the method reads (all, unless a method picks some)."""
        return list(range(ports))

    def _learn(self, sweep: Sweep) -> None:
        raise NotImplementedError

"""The estimator every calibrator is: settings, declarations, reading, description, files.

:class:`BaseCalibrator` is small: its behaviour comes from mixins (settings from
:mod:`~wavemeter.calibration.contract.params`, reading from
:mod:`~wavemeter.calibration.contract.reading` and
:mod:`~wavemeter.calibration.contract.streaming`). What a class adds is its declarations
(``method``, ``requires``, ``capabilities``, ``reading_outputs``), its ``fit``, the
methods it reads with (``_phase`` at least) and its learned state for files (``_state`` /
``_set_state``). Consumers ask a calibration what it declares, never test its type:
``parts()`` for the sub-calibrations of a composite, ``describe()`` for what it learned.
Writing a calibrator of your own: see the user guide's plug-in page.
"""

from __future__ import annotations

import types
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...exceptions import InputError, WavemeterError, shown
from ...validation import check_fitted, check_positive
from ..files.document import save_calibration, state_array
from ..files.fields import (
    NOISE_RELATIVE,
    OFFSET_RULE,
    SPREAD_RELATIVE,
    FieldRule,
    RecordRule,
    ScaleRule,
    largest_magnitude,
    rule_table,
)
from ..files.registry import register
from .figures import FigureData, FringePanel
from .params import ParamsMixin
from .reading import ReadingMixin
from .records import READING_INPUTS
from .streaming import StreamMixin
from .summary import Check, FitReport, FitValue

__all__ = [
    "BaseCalibrator",
    "CAPABILITIES",
    "COMMON_DIAGNOSTICS",
    "MAX_MAP_CONDITION",
    "Part",
]

#: largest condition number of a loaded map: beyond it the map has lost a dimension
MAX_MAP_CONDITION = 1e10
#: what a calibrator may offer besides predict/phase/flags/readout
CAPABILITIES = (
    "frequency_std",  # frequency_std_hz: the standard deviation of each reading
    "crlb",  # crlb_hz: the Cramer-Rao bound of each reading
    "power_monitor",  # fit takes a source-power monitor
    "reanchor",  # reanchor: a corrected copy from readings of reference lines
    "fit_chunks",  # fit_chunks: a sweep read in chunks, in bounded memory
)


#: entries of ``diagnostics_`` that mean the same for every calibrator (the checks every fit
#: makes, its warnings, a re-anchoring); a method's own records are presented by its
#: ``summary()``
COMMON_DIAGNOSTICS = (
    "fsr_estimate_hz",
    "ports",
    "fit",
    "temperature_range_k",
    "diagnostic_samples",
    "reanchor",
    "warnings",
)


@dataclass(frozen=True)
class Part:
    """One labelled sub-calibration of a composite (a set's window, a cascade's stage).

    Attributes
    ----------
    label : str
        How people read it (``"window 3 (193.40 to 193.45 THz)"``, ``"stage 2 (500 GHz)"``).
    kind : {"window", "stage"}
        What the composite is made of.
    calibration : BaseCalibrator
        The fitted sub-calibration.
    range_hz : (float, float)
        The frequencies it reads (Hz): a window's edges, a stage's band.

    Examples
    --------
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(800, span_fsr=4)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> cal_set = wm.CalibrationSet(fsr_hz=50e9).fit(powers, f_hz)
    >>> parts = cal_set.parts()  # a set's windows: one fitted calibrator each
    >>> len(parts), parts[0].kind
    (4, 'window')
    >>> print(parts[0].label)
    window 0 (193.296864 to 193.348368 THz)
    >>> print(f"{parts[0].calibration.fsr_hz_ / 1e9:.2f} GHz")
    51.50 GHz
    """

    label: str
    kind: str
    calibration: BaseCalibrator
    range_hz: tuple


class BaseCalibrator(ParamsMixin, ReadingMixin, StreamMixin):
    """Common machinery of every calibrator; not used on its own (module docstring).

    Examples
    --------
    A calibrator of your own subclasses ``BaseCalibrator`` (reading, flags, streaming,
    files, the summary) and :class:`SweepFitMixin` (the checked fit), and writes its
    settings, ``_learn`` and ``_phase``. This one learns the map at a known FSR; a
    ``method`` tag (not given here) would register it for files and the command line:

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
    >>> cal = KnownDelayCalibrator(fsr_hz=device.true_fsr_hz).fit(powers, f_hz)

    The contract gives it the rest: checked readings, per-reading status and uncertainty:

    >>> readings = np.vstack([powers[100:102], np.full(3, np.nan)])  # the last one not a reading
    >>> reading = cal.readout(readings)
    >>> print(np.round((reading.frequency_hz - f_hz[[100, 101, 0]]) / 1e6), reading.flags)
    [-2. -3. nan] [0 0 8]
    >>> print(f"{cal.calibration_rms_hz_ / 1e6:.0f} MHz RMS on its own sweep")
    14 MHz RMS on its own sweep
    """

    #: the tag in calibration files; a class with a tag of its own registers itself
    method: ClassVar[str] = ""
    #: per-reading inputs (names from READING_INPUTS) that predict/phase need
    requires: ClassVar[frozenset[str]] = frozenset()
    #: optional features (names from CAPABILITIES) the class provides
    capabilities: ClassVar[frozenset[str]] = frozenset({"power_monitor"})
    #: extra per-reading outputs (name -> unit) that ``readout`` and ``stream`` give
    reading_outputs: ClassVar[Mapping[str, str]] = types.MappingProxyType({})
    #: the method reads absolute frequency without a coarse input (a cascade of stages)
    absolute_frequency: ClassVar[bool] = False
    #: ports with a fringe the method needs among those it reads (the cone model: 3)
    fringe_ports_needed: ClassVar[int] = 3
    #: the comparison method is expected to misfit this method's sweeps (sweeps at several
    #: temperatures, over many FSRs): its warnings belong to the report, not to the user
    comparison_misfits_expected: ClassVar[bool] = False
    #: what each number of the file's ``state`` may hold: field path -> rule (or rules),
    #: added to or replaced by subclasses (:mod:`wavemeter.calibration.files.fields`)
    state_rules: ClassVar[Mapping[str, object]] = rule_table({})
    #: what each number of the file's ``reading_model`` may hold; the sweep's highest total
    #: power is the power scale of a class whose state sets none
    reading_model_rules: ClassVar[Mapping[str, object]] = rule_table(
        {
            "dark_w": OFFSET_RULE,
            "offset_w": OFFSET_RULE,
            "total_power_range_w": (
                ScaleRule(
                    "the sweep's lowest and highest total power",
                    largest_magnitude,
                    "the sweep's highest total power",
                ),
                FieldRule(
                    "the sweep's lowest and highest total power",
                    "W",
                    NOISE_RELATIVE[0],
                    SPREAD_RELATIVE,
                    scale="power_w",
                    open_low=True,
                ),
            ),
        }
    )
    #: the records of ``diagnostics_`` a report presents (the common ones' presentation is
    #: tolerant: only the ports' list must be one)
    diagnostics_rules: ClassVar[Mapping[str, object]] = rule_table(
        {"ports": RecordRule("the ports' records", "list")}
    )
    #: learned attributes common to every calibrator, saved by every calibration file
    common_attributes: ClassVar[tuple[str, ...]] = (
        "fsr_hz_",
        "center_hz_",
        "span_hz_",
        "n_ports_",
        "n_samples_",
        "port_names_",
        "calibration_rms_hz_",
    )

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if "method" in cls.__dict__ and cls.method:
            register(cls.method, cls)
        declared = cls.__dict__.get("capabilities")
        offered = set(declared) if isinstance(declared, frozenset) else set()
        unknown = (set(cls.requires) - set(READING_INPUTS)) | (offered - set(CAPABILITIES))
        if unknown:
            raise WavemeterError(
                f"{cls.__qualname__} declares unknown inputs or capabilities {unknown}"
            )

    def __init__(self, fsr_hz: float = 50e9):
        self.fsr_hz = fsr_hz

    @property
    def method_label(self) -> str:
        """The method as people read it (the file tag, or e.g. ``"learned per FSR"``)."""
        return type(self).method

    def __repr__(self) -> str:
        text = self._settings_repr()
        if hasattr(self, "fsr_hz_"):
            text += (
                f" fitted: FSR {self.fsr_hz_ / 1e9:.6g} GHz, {self.n_ports_} ports, "
                f"{self.n_samples_} samples, RMS {self.calibration_rms_hz_ / 1e6:.3g} MHz"
            )
        return text

    def _check_params(self) -> None:
        check_positive("fsr_hz", self.fsr_hz)

    # ------------------------------------------------------------------ fitting
    def _start_fit(self, span_hz: tuple[float, float], names: list, samples: int, dark) -> None:
        """The sweep's layout as the fitted attributes keep it; no offsets yet."""
        low, high = span_hz
        self.center_hz_ = 0.5 * (low + high)
        self.span_hz_ = (low, high)
        self.n_ports_ = len(names)
        self.n_samples_ = samples
        self.port_names_ = names
        self.dark_w_ = dark
        self.offset_w_ = np.zeros(len(names))

    def _take_power_range(self, powers_w: np.ndarray) -> None:
        """The sweep's total power range (W), offset-corrected as readings will be: the
        range the ``POWER_RANGE`` flag compares readings with."""
        total = (powers_w - self.offset_w_).sum(axis=1)
        self.total_power_range_w_ = (float(total.min()), float(total.max()))

    def reanchor(self, powers, frequency_hz, **inputs):
        """A copy re-anchored to readings of reference lines, where ``"reanchor"`` is a
        capability.

        Raises
        ------
        InputError
            For a class that cannot be re-anchored.
        """
        self._require_capability("reanchor", "cannot be re-anchored")
        raise NotImplementedError

    # ------------------------------------------------------------------ what a report shows
    def comparison(self, port_phases_rad=None) -> BaseCalibrator:
        """An unfitted calibrator of the method this one is compared with in its report
        (fitted on the same sweep); ``port_phases_rad`` for a conventional comparison.

        Raises
        ------
        InputError
            When no other method can be compared with this one (the message says why).
        """
        raise InputError(
            f"a {self.method_label} calibration names no other method to compare it with "
            "on its sweep: evaluate it alone, or beside another calibration file",
            parameter="comparison",
        )

    def fringe_panels(
        self, frequency_hz, powers_w, monitor_w=None, temperature_k=None
    ) -> tuple[FringePanel, ...]:
        """The sweep's readings with the fitted model's fringes, one panel per part
        (paper Fig. 4b, 7a); none for a method without a model of the fringes."""
        return ()

    def object_samples(self, powers_w, frequency_hz, temperature_k=None) -> np.ndarray | None:
        """Object-space samples ``r [cos t, sin t]`` (N', 2) of readings of known frequency
        under the fitted map, at unit source power (paper Fig. 4a); None for a method
        without a map."""
        return None

    def report_figures(self, noise_std_hz: float | None = None) -> tuple[FigureData, ...]:
        """Figures of the fit the method adds to its report (``noise_std_hz``: the bound's
        RMS on the evaluation readings, as the noise level to judge them by)."""
        return ()

    def evaluation_checks(self, powers_w, frequency_hz) -> tuple[Check, ...]:
        """Checks of its own on readings of known frequency (Hz), beyond their error."""
        return ()

    # ------------------------------------------------------------------ description
    def parts(self) -> tuple[Part, ...]:
        """The labelled sub-calibrations of a composite (a set's windows, a cascade's
        stages), in order; empty for a single calibration."""
        return ()

    def summary(self) -> FitReport:
        """The fit report: learned values with standard errors, settings, diagnostics.

        Returns
        -------
        FitReport
            ``report["fsr_hz"].value`` / ``.stderr`` (Hz), ``report.as_dict()``
            (JSON-ready), ``str(report)`` (aligned text); one report per part.
        """
        check_fitted(self)
        values = {
            "fsr_hz": FitValue(self.fsr_hz_, self._fsr_std_hz(), "Hz"),
            "design_fsr_hz": FitValue(self._design_fsr_hz(), None, "Hz"),
            "center_hz": FitValue(self.center_hz_, None, "Hz"),
            "calibration_rms_hz": FitValue(self.calibration_rms_hz_, None, "Hz"),
            **self._summary_values(),
        }
        parts = self.parts()
        return FitReport(
            method=type(self).method,
            method_label=self.method_label,
            settings=self.get_params_for_file(),
            values=values,
            ports=tuple(self.port_names_),
            samples=self.n_samples_,
            span_hz=tuple(self.span_hz_),
            diagnostics=self.diagnostics_,
            windows=tuple(part.calibration.summary() for part in parts),
            windows_are=f"{parts[0].kind}s" if parts else "windows",
        )

    describe = summary

    def _fsr_std_hz(self) -> float | None:
        """Standard error of the fitted FSR (Hz), where the method knows it."""
        return None

    def _design_fsr_hz(self) -> float:
        """The design FSR (Hz) ``fsr_hz_`` is compared with in the summary."""
        return float(self.fsr_hz)

    def _summary_values(self) -> dict:
        """Method-specific learned values for :meth:`summary` (name -> FitValue)."""
        return {}

    # ------------------------------------------------------------------ files
    def save(self, path, metadata: dict | None = None) -> None:
        """Write the calibration to a versioned JSON file (atomically)."""
        save_calibration(self, path, metadata)

    def _state(self) -> dict:
        """Method-specific learned state as JSON-ready values."""
        raise NotImplementedError

    def _set_state(self, state: dict) -> None:
        raise NotImplementedError

    def _reading_model_state(self) -> dict:
        """Dark readings, fitted offsets and the sweep's total power range, JSON-ready."""
        power_range = self.total_power_range_w_
        return {
            "dark_w": None if self.dark_w_ is None else self.dark_w_.tolist(),
            "offset_w": self.offset_w_.tolist(),
            "total_power_range_w": None if power_range is None else list(power_range),
        }

    def _set_reading_model_state(self, state: dict) -> None:
        """Restore :meth:`_reading_model_state`; missing fields (schema 1) mean none."""
        ports = (self.n_ports_,)
        self.dark_w_ = state_array(state, "dark_w", ports) if state.get("dark_w") else None
        self.offset_w_ = (
            state_array(state, "offset_w", ports) if "offset_w" in state else np.zeros(ports)
        )
        if state.get("total_power_range_w") is None:
            self.total_power_range_w_ = None
        else:
            low, high = state_array(state, "total_power_range_w", (2,))
            if not 0 < low <= high:
                raise InputError(
                    "field 'total_power_range_w' must be 0 < low <= high (W), got "
                    f"{[float(low), float(high)]}"
                )
            self.total_power_range_w_ = (float(low), float(high))

    def _check_state(self) -> None:
        """Check a loaded state against the model: a full-rank finite (n, 3) map (when the
        method has one) and a delay that is ``1 / fsr_hz`` (when it has one)."""
        matrix = vars(self).get("map_")
        if matrix is not None:
            if matrix.shape != (self.n_ports_, 3) or not np.all(np.isfinite(matrix)):
                raise InputError(
                    f"map must be {self.n_ports_} x 3 finite numbers, got shape {matrix.shape}"
                )
            singular = np.linalg.svd(matrix, compute_uv=False)
            if not (singular[-1] > 0 and singular[0] / singular[-1] < MAX_MAP_CONDITION):
                raise InputError(
                    f"map must have full rank 3 (condition number below {MAX_MAP_CONDITION:g}), "
                    f"got singular values {singular.tolist()}"
                )
        delay = vars(self).get("delay_s_")
        if delay is not None and not (
            np.isfinite(delay) and delay > 0 and abs(delay * self.fsr_hz_ - 1.0) < 1e-9
        ):
            raise InputError(
                f"delay_s {shown(delay)} must be > 0 and equal 1 / fsr_hz "
                f"({shown(1.0 / self.fsr_hz_)} s)"
            )

"""What a cascade checks of its hand-overs on its own sweep, at fit time.

:class:`HandoverChecksMixin` gives :class:`~wavemeter.calibration.methods.cascade.CascadeCalibrator`
each hand-over's record on the sweep (FSR ratio, margin in standard deviations, the
largest ratio the noise allows, predicted and seen wrong orders), refuses a hand-over
whose wrong-order rate exceeds ``max_order_error``, warns when the sweep saw improbably
many wrong orders, measures the coarsest stage's edge margin and each stage's error
beyond its uncertainty, and says what a coarsest stage's misfit costs in a cascade.
Theory: the docs' cascade page.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special, stats

from ...exceptions import CalibrationWarning, InputError
from ...model.orders import handover_error_rate
from ...units import frequency_text
from ..files.fields import MAX_FSR_RATIO, MAX_MARGIN_STD, record_number
from .cascade_reading import NOISE_P_VALUE, CascadeReading

__all__ = ["HANDOVER_CAUSE", "HandoverChecksMixin", "handover_rules", "stage_label"]

#: the cause of a warning that the sweep saw more wrong orders than the rates predict
HANDOVER_CAUSE = "order_handover"
HANDOVER_REMEDY = (
    "look for steps in the sweep (a mode hop of the laser, a wavelength reference that "
    "slipped, a stage that drifted) and re-record it"
)
#: misfit causes of the coarsest stage whose cost in a cascade its warning states
SWEEP_MISFIT_CAUSES = (
    "power_drift",
    "detector_offset",
    "phase_drift",
    "dispersion",
    "other_misfit",
)
#: p-value below which the wrong orders seen on the sweep contradict the predicted ones
HANDOVER_P_VALUE = 1e-6


#: most stages a cascade's record may name
MAX_STAGES = 100
#: the numbers of a hand-over's record: key, what, unit, low, high, whole, scale (of the
#: bounds: the band for a standard deviation, the sweep's readings for a count)
_HANDOVER_NUMBERS = (
    ("from_stage", "the coarser stage", "", 1, MAX_STAGES, True, None),
    ("to_stage", "the finer stage", "", 2, MAX_STAGES, True, None),
    ("ratio", "the FSR ratio", "", 1.0, MAX_FSR_RATIO, False, None),
    ("median_std_hz", "the median standard deviation", "Hz", 0.0, 1.0, False, "band_hz"),
    ("margin_std", "the median margin", "std", -MAX_MARGIN_STD, MAX_MARGIN_STD, False, None),
    ("worst_margin_std", "the least margin", "std", -MAX_MARGIN_STD, MAX_MARGIN_STD, False, None),
    ("largest_usable_ratio", "the largest usable ratio", "", 0.0, MAX_MARGIN_STD, False, None),
    ("predicted_rate", "the predicted wrong-order rate", "", 0.0, 1.0, False, None),
    ("expected_wrong", "the wrong orders expected", "", 0.0, 1.0, False, "samples"),
    ("wrong_on_sweep", "the wrong orders seen on the sweep", "", 0, 1.0, True, "samples"),
)


def handover_rules(prefix: str) -> dict:
    """What each number of the hand-overs' records under ``prefix`` may hold (a calibration
    file's rules, :mod:`~wavemeter.calibration.files.fields`)."""
    return {
        f"{prefix}.*.{key}": record_number(what, unit, low, high, integer, scale)
        for key, what, unit, low, high, integer, scale in _HANDOVER_NUMBERS
    }


def stage_label(index: int, fsr_hz: float) -> str:
    """``stage 2 (500 GHz)``: a stage as messages name it (``index`` from 0)."""
    return f"stage {index + 1} ({frequency_text(fsr_hz)})"


class HandoverChecksMixin:
    """The hand-over checks of a cascade's fit (module docstring)."""

    def _handovers(self, chain: CascadeReading, frequency_hz: np.ndarray) -> list[dict]:
        """Every hand-over's record on the sweep (``handovers_``); refuses a hand-over whose
        expected wrong-order rate exceeds ``max_order_error``."""
        records = []
        design = self._design_fsrs_hz()
        required = math.sqrt(2.0) * float(special.erfcinv(self.max_order_error))
        for index in range(1, len(self.stages_)):
            coarse, fine = self.stages_[index - 1], self.stages_[index]
            fsr = fine.fsr_hz_at(chain.frequency_hz[index])
            std = np.hypot(chain.std_hz[index - 1], chain.std_hz[index])
            rate = handover_error_rate(fsr, std)
            # phase std (rad) of both stages: the ratio at which the margin is `required`
            coarse_phase = np.median(chain.std_hz[index - 1] * 2.0 * np.pi / coarse.fsr_hz_)
            fine_phase = np.median(chain.std_hz[index] * 2.0 * np.pi / fine.fsr_hz_)
            usable = math.sqrt(max((np.pi / required) ** 2 - fine_phase**2, 0.0)) / coarse_phase
            ratio = coarse.fsr_hz_ / fine.fsr_hz_
            # the order this hand-over took against the one the recorded frequency has,
            # each stage's error taken within its own order
            before = self._within_order_error_hz(chain, frequency_hz, index - 1)
            after = self._within_order_error_hz(chain, frequency_hz, index)
            wrong = np.round((before - after) / fsr) != 0
            record = {
                "from_stage": index,
                "to_stage": index + 1,
                "ratio": float(ratio),
                "median_std_hz": float(np.median(std)),
                "margin_std": float(np.median(0.5 * fsr / std)),
                "worst_margin_std": float(np.min(0.5 * fsr / std)),
                "largest_usable_ratio": float(usable),
                "predicted_rate": float(np.mean(rate)),
                "expected_wrong": float(np.sum(chain.error_probability[index])),
                "wrong_on_sweep": int(np.count_nonzero(wrong)),
            }
            if record["predicted_rate"] > self.max_order_error:
                raise InputError(
                    f"{stage_label(index - 1, design[index - 1])} cannot pick the fringe order "
                    f"of {stage_label(index, design[index])}: its frequency noise on the sweep "
                    f"({frequency_text(record['median_std_hz'])} with the finer stage's, "
                    f"median) is {2.0 * record['median_std_hz'] / float(np.median(fsr)):.3g} "
                    "of the finer stage's half FSR, a wrong order for "
                    f"{record['predicted_rate']:.3g} of the readings (max_order_error "
                    f"{self.max_order_error:g}); at this noise the largest usable FSR ratio "
                    f"is {usable:.3g} and these stages have {ratio:.3g}: lower the noise "
                    "(more power per stage, averaged readings) or add a stage between them",
                    parameter="fsr_hz",
                )
            records.append(record)
        return records

    def _within_order_error_hz(
        self, chain: CascadeReading, frequency_hz: np.ndarray, index: int
    ) -> np.ndarray:
        """Stage ``index``'s error (Hz) against the recorded frequencies, within its order
        (the coarsest stage's as it is)."""
        error = chain.frequency_hz[index] - frequency_hz
        if index == 0:
            return error
        fsr = self.stages_[index].fsr_hz_at(frequency_hz)
        return error - fsr * np.round(error / fsr)

    def _edge_margin_std(self, chain: CascadeReading, frequency_hz: np.ndarray) -> float:
        """The coarsest stage's unique range beyond the band, in that stage's standard
        deviations of the sweep readings at the band's ends (the smaller end)."""
        ends = np.array([np.argmin(frequency_hz), np.argmax(frequency_hz)])
        model = self.stages_[0].band_model_
        end_hz = frequency_hz[ends]
        offset = model.phase_rad(end_hz) - model.phase_rad(np.array([self.center_hz_]))
        distance = (np.pi - np.abs(offset)) / model.phase_slope_rad_per_hz(end_hz)
        return float(np.min(distance / chain.std_hz[0][ends]))

    def _coarsest_context(self, note: CalibrationWarning) -> CalibrationWarning:
        """A misfit of the coarsest stage, with what it means in a cascade: its
        uncertainties (the model-free noise, the error its sweep showed beyond them) carry
        the misfit into the hand-over margin, not into the answer."""
        label = stage_label(0, self._design_fsrs_hz()[0])
        if note.cause not in SWEEP_MISFIT_CAUSES or not str(note).startswith(f"{label}:"):
            return note
        margin = self.handovers_[0]["margin_std"]
        context = (
            "in a cascade the coarsest stage's uncertainties include what its sweep shows "
            "beyond the noise, so this costs hand-over margin (now "
            f"{margin:.3g} standard deviations to stage 2), not the finest stage's accuracy"
        )
        return CalibrationWarning(
            f"{note}; {context}", cause=note.cause, remedy=f"{note.remedy}; {context}"
        )

    def _handover_notes(self) -> list[CalibrationWarning]:
        """A warning per hand-over where the sweep saw improbably many wrong orders."""
        notes = []
        for record in self.handovers_:
            seen, expected = record["wrong_on_sweep"], record["expected_wrong"]
            if seen and stats.poisson.sf(seen - 1, expected) < HANDOVER_P_VALUE:
                notes.append(
                    CalibrationWarning(
                        f"stage {record['from_stage']} handed stage {record['to_stage']} "
                        f"another fringe order than the recorded frequency has on {seen} sweep "
                        f"readings, where the stages' uncertainties predict {expected:.3g}: "
                        "those readings are not where the sweep says, or the stages disagree "
                        f"beyond their noise; {HANDOVER_REMEDY}",
                        cause=HANDOVER_CAUSE,
                        remedy=HANDOVER_REMEDY,
                    )
                )
        return notes

    def _model_error_hz(self, chain: CascadeReading, frequency_hz: np.ndarray) -> np.ndarray:
        """Each stage's error (Hz) on the sweep beyond its uncertainty, where significant.

        A stage whose model misses part of the chip (the coarsest stage over less than its
        FSR) reads the sweep with errors its ``std`` does not explain. Robustly, so that a
        few bad sweep readings do not count: when more z-scores than chance lie beyond
        the normal quartile ``Q`` (binomial at ``NOISE_P_VALUE``), their spread ``r =
        median |z| / Q`` gives the excess ``sqrt(r^2 - 1) rms(std)``, added to every
        reading's std in quadrature.
        """
        quartile = float(special.ndtri(0.75))
        excess = np.zeros(len(self.stages_))
        for index in range(len(self.stages_)):
            error = self._within_order_error_hz(chain, frequency_hz, index)
            std = chain.std_hz[index]
            z = np.abs(error / std)
            beyond = int(np.count_nonzero(z > quartile))
            if stats.binom.sf(beyond - 1, z.size, 0.5) < NOISE_P_VALUE:
                spread = float(np.median(z)) / quartile
                excess[index] = math.sqrt(max(spread**2 - 1.0, 0.0) * np.mean(std**2))
        return excess

    def _stage_records(self, chain: CascadeReading, frequency_hz: np.ndarray) -> list[dict]:
        records = []
        for index, stage in enumerate(self.stages_):
            error = chain.frequency_hz[index] - frequency_hz
            if index == 0:
                z = error / chain.std_hz[index]
            else:
                # modulo the stage's FSR: its precision, whatever order it was handed
                fsr = stage.fsr_hz_at(chain.frequency_hz[index])
                z = (error - fsr * np.round(error / fsr)) / chain.std_hz[index]
            records.append(
                {
                    "stage": index + 1,
                    "ports": [self.port_names_[column] for column in self.stage_ports_[index]],
                    "fsr_hz": float(stage.fsr_hz_),
                    "phase_order": stage.phase_order_,
                    "map_order": stage.map_order_,
                    "rms_hz": float(np.sqrt(np.mean(error**2))),
                    "median_std_hz": float(np.median(chain.std_hz[index])),
                    "z_std": float(np.std(z)),
                }
            )
        return records

"""A cascade's calibration file state: its stages (each a wide-band calibration of its
columns), their hand-overs and the cascade's own numbers, written and read back."""

from __future__ import annotations

import numpy as np

from ...exceptions import InputError
from ..files.document import calibrator_fields, calibrator_from_fields
from ..files.state import state_array, state_float

__all__ = ["CascadeStateMixin"]

#: the method of every stage (a wide-band calibration of the stage's columns)
STAGE_METHOD = "wideband"


class CascadeStateMixin:
    """``_state``, ``_set_state`` and ``_check_state`` of :class:`CascadeCalibrator`."""

    def _state(self) -> dict:
        return {
            "stage_ports": [list(block) for block in self.stage_ports_],
            "stages": [calibrator_fields(stage) for stage in self.stages_],
            "handovers": self.handovers_,
            "edge_margin_std": self.edge_margin_std_,
            "cone_distance_median": self.cone_distance_median_.tolist(),
            "model_error_hz": self.model_error_hz_.tolist(),
        }

    def _set_state(self, state: dict) -> None:
        design = self._design_fsrs_hz()
        documents = state.get("stages")
        if not isinstance(documents, list) or len(documents) != len(design):
            raise InputError(f"field 'stages' must list {len(design)} stage calibrations")
        blocks = state.get("stage_ports")
        if not isinstance(blocks, list):
            raise InputError("field 'stage_ports' must list the columns of each stage")
        saved, self.stage_ports = (
            self.stage_ports,
            tuple(tuple(block) if isinstance(block, list) else block for block in blocks),
        )
        try:
            columns = self._stage_columns(self.n_ports_)
        finally:
            self.stage_ports = saved
        stages = [
            calibrator_from_fields(document, f"stage {index + 1}")
            for index, document in enumerate(documents)
        ]
        for index, (stage, block) in enumerate(zip(stages, columns, strict=True)):
            if stage.method != STAGE_METHOD or stage.n_ports_ != len(block):
                raise InputError(
                    f"stage {index + 1} must be a 'wideband' calibration of {len(block)} ports, "
                    f"got {type(stage).method!r} with {stage.n_ports_}"
                )
        handovers = state.get("handovers")
        if not isinstance(handovers, list) or len(handovers) != len(design) - 1:
            raise InputError(f"field 'handovers' must list {len(design) - 1} hand-overs")
        self.stages_ = stages
        self.stage_ports_ = columns
        self.stage_fsrs_hz_ = np.array([stage.fsr_hz_ for stage in stages])
        self.fsr_hz_ = float(self.stage_fsrs_hz_[-1])
        self.handovers_ = handovers
        self.edge_margin_std_ = state_float(state, "edge_margin_std")
        self.cone_distance_median_ = state_array(state, "cone_distance_median", (len(design),))
        self.model_error_hz_ = state_array(state, "model_error_hz", (len(design),))

    def _check_state(self) -> None:
        super()._check_state()
        record = (self.diagnostics_ or {}).get("cascade")
        if record and len(record["stages"]) != len(self.stages_):
            raise InputError(
                f"field 'diagnostics.cascade.stages' must list the {len(self.stages_)} stages, "
                f"got {len(record['stages'])}"
            )

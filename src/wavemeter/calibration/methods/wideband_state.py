"""What a wide-band calibration keeps in its file: the state and the rules its numbers obey.

:class:`BandStateMixin` writes and reads the state of
:class:`~wavemeter.calibration.methods.wideband.WidebandCalibrator` (orders, the model
phase's coefficients and what ``phase_coefficients_`` are of, the map, the noise model,
the covariance of every fitted number) and declares each field's physical range
(:mod:`~wavemeter.calibration.files.fields`). Theory: the docs' wide-band page
(``docs/theory/wideband.rst``, "What the phase coefficients are").
"""

from __future__ import annotations

import numpy as np

from ...exceptions import InputError, shown
from ..files import fields
from ..files.state import state_array, state_float
from ..models.wideband_orders import MAX_MAP_ORDER, MAX_PHASE_ORDER, parameter_count

__all__ = ["MAX_PHASE_TERM", "PHASE_DEFINITIONS", "BandStateMixin"]

#: largest phase coefficient a file may hold, in units of the phase a linear term gives half
#: the band (pi span / FSR): dispersion changes the FSR across a band by percents, not tenfold
MAX_PHASE_TERM = 10.0

#: what ``phase_coefficients_`` are of: the fringe phase, or (files written before it was
#: reported) the model phase ``t``
PHASE_DEFINITIONS = ("fringe", "model")


class BandStateMixin:
    """The file state of a wide-band calibration (module docstring)."""

    #: what each number of the file's state may hold (:mod:`~wavemeter.calibration.files.fields`)
    state_rules = fields.rule_table(
        {
            "phase_order": fields.FieldRule(
                "the phase polynomial's order", "", 1, MAX_PHASE_ORDER, integer=True
            ),
            "map_order": fields.FieldRule("the map's order", "", 0, MAX_MAP_ORDER, integer=True),
            "n_parameters": fields.FieldRule("the fitted parameters", "", 1, integer=True),
            "phase_coefficients_rad": fields.FieldRule(
                "a phase coefficient",
                "rad",
                high=MAX_PHASE_TERM,
                scale="band_phase_rad",
                magnitude=True,
            ),
            "map_coefficients": (
                fields.ScaleRule(
                    "the map's coefficients",
                    fields.largest_singular_value,
                    "the largest singular value of the map's mean over the band",
                ),
                fields.FieldRule(
                    "a map coefficient",
                    "W",
                    high=fields.SPREAD_RELATIVE,
                    scale="power_w",
                    magnitude=True,
                ),
            ),
            **fields.NOISE_MODEL_RULES,
            "parameter_covariance": fields.CovarianceRule(
                tail=(("a phase coefficient", "band_phase_rad", MAX_PHASE_TERM),),
                tail_repeats="phase_order",
            ),
        }
    )

    def _state(self) -> dict:
        return {
            "phase_order": self.phase_order_,
            "map_order": self.map_order_,
            "phase_coefficients_rad": self.phase_coefficients_rad_.tolist(),
            "phase_definition": self.phase_definition_,
            "map_coefficients": self.map_coefficients_.tolist(),
            "n_parameters": self.n_parameters_,
            "cost_w2": self.cost_,
            "residual_rms_w": self.residual_rms_,
            "noise_std_w": self.noise_std_w_,
            "port_noise_std_w": self.port_noise_std_w_.tolist(),
            "noise_dof": self.noise_dof_,
            "parameter_covariance": self.parameter_covariance_.tolist(),
            **self._off_model_state(),
        }

    def _set_state(self, state: dict) -> None:
        ports = self.n_ports_
        phase_order = int(state_float(state, "phase_order", minimum=1, maximum=MAX_PHASE_ORDER))
        map_order = int(state_float(state, "map_order", minimum=0, maximum=MAX_MAP_ORDER))
        if phase_order != state["phase_order"] or map_order != state["map_order"]:
            raise ValueError("fields 'phase_order' and 'map_order' must be integers")
        self.phase_order_, self.map_order_ = phase_order, map_order
        self.half_span_hz_ = 0.5 * (self.span_hz_[1] - self.span_hz_[0])
        if not self.half_span_hz_ > 0:
            raise ValueError("field 'span_hz' must have low < high for a wide-band calibration")
        definition = state.get("phase_definition", "model")  # files before it: model
        if definition not in PHASE_DEFINITIONS:
            raise InputError(
                f"field 'phase_definition' must be one of {PHASE_DEFINITIONS}, got "
                f"{shown(definition, as_in_file=True)}"
            )
        coefficients_rad = state_array(state, "phase_coefficients_rad", (phase_order,))
        linear = 2.0 * np.pi * self.half_span_hz_ / self.fsr_hz_  # the delay, in rad
        if (
            definition == "model"
            and not abs(coefficients_rad[0] / linear - 1.0) <= fields.DELAY_RTOL
        ):
            raise InputError(
                "field 'phase_coefficients_rad' must start with the linear term 2 pi (half the "
                f"span) / fsr_hz = {linear!r} rad (the delay), got {coefficients_rad.tolist()}"
            )
        header_fsr_hz = self.fsr_hz_
        try:
            self._set_model(
                coefficients_rad,
                state_array(state, "map_coefficients", (map_order + 1, ports, 3)),
                definition,
            )
        except InputError as exc:  # the fit's wording: say which field
            raise InputError(
                f"field 'phase_coefficients_rad' must give a phase rising across the band: {exc}"
            ) from exc
        if not abs(self.fsr_hz_ / header_fsr_hz - 1.0) <= fields.DELAY_RTOL:  # fringe phase
            raise InputError(
                "field 'phase_coefficients_rad' (with the map's fringe phase) must give the "
                f"delay 1 / fsr_hz = {1.0 / header_fsr_hz!r} s, got {self.delay_s_!r} s"
            )
        self.cost_ = state_float(state, "cost_w2", minimum=0.0)
        self.residual_rms_ = state_float(state, "residual_rms_w", minimum=0.0)
        self.noise_std_w_ = state_float(state, "noise_std_w", minimum=0.0)
        self.port_noise_std_w_ = state_array(state, "port_noise_std_w", (ports,))
        self.noise_dof_ = state_float(state, "noise_dof", minimum=2.0, open_minimum=True)
        columns = 3 * (map_order + 1)
        self.parameter_covariance_ = state_array(state, "parameter_covariance", (None, None))
        sizes = (ports * columns + phase_order, ports * (columns + 1) + phase_order)
        size = self.parameter_covariance_.shape[0]
        if self.parameter_covariance_.shape != (size, size) or size not in sizes:
            raise ValueError(
                f"field 'parameter_covariance' must be square of size {sizes[0]} or {sizes[1]}, "
                f"got shape {self.parameter_covariance_.shape}"
            )
        self.n_parameters_ = parameter_count(ports, phase_order, map_order, self._affine())
        if state.get("n_parameters") != self.n_parameters_:
            raise InputError(
                f"field 'n_parameters' must be {self.n_parameters_}, the parameters of the orders "
                f"and ports, got {shown(state.get('n_parameters'), as_in_file=True)}"
            )
        self._set_off_model_state(state)

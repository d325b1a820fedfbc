"""What the numbers of a thermal calibration file may hold, beyond a learned one's.

The rates are at most those of a delay changing by ``RELATIVE_RATE_PER_K`` per kelvin (the
bias phase's relative to the optical phase ``2 pi centre / FSR``); temperatures are in K
(:data:`~wavemeter.calibration.files.fields.TEMPERATURE_K`); the covariance's nonlinear
parameters (delay, bias rate, delay rate) have standard errors within those bounds.
"""

from __future__ import annotations

from ..files import fields

__all__ = ["THERMAL_DIAGNOSTICS_RULES", "THERMAL_STATE_RULES"]

THERMAL_STATE_RULES = fields.rule_table(
    {
        "thermal_phase_rad_per_k": fields.FieldRule(
            "the bias phase's rate",
            "rad/K",
            high=fields.RELATIVE_RATE_PER_K,
            scale="optical_phase_rad",
            magnitude=True,
        ),
        "thermal_delay_per_k": fields.FieldRule(
            "the delay's relative rate", "1/K", high=fields.RELATIVE_RATE_PER_K, magnitude=True
        ),
        "reference_temperature_k": fields.TEMPERATURE_RULE,
        "temperature_range_k": fields.TEMPERATURE_RULE,
        "parameter_covariance": fields.CovarianceRule(
            tail=(
                ("the delay", "delay_s", 1.0),
                ("the bias rate", "optical_phase_rad", fields.RELATIVE_RATE_PER_K),
                ("the delay rate", None, fields.RELATIVE_RATE_PER_K),
            )
        ),
    }
)

#: the record the summary presents: the calibrated temperatures and the unambiguous rate
THERMAL_DIAGNOSTICS_RULES = fields.rule_table(
    {
        "thermal": fields.RecordRule("the thermal record", "object"),
        "thermal.temperatures_k.*": fields.FieldRule(
            "a calibrated temperature", "K", *fields.TEMPERATURE_K, scalar=True
        ),
        "thermal.unambiguous_phase_rate_rad_per_k": fields.FieldRule(
            "the unambiguous bias rate", "rad/K", 0.0, scalar=True
        ),
    }
)

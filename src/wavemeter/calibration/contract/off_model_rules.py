"""What the ``off_model`` record of a calibration file may hold: the physical range of each
of its numbers (the loader's rules; the relations between them are checked where the record
is read back)."""

from __future__ import annotations

from ..files.fields import NOISE_RELATIVE, SPREAD_RELATIVE, FieldRule, rule_table
from .off_model_residual import MAX_HARMONICS, MAX_POWER_DEGREE

__all__ = ["MAX_DISTANCE", "MAX_SPREAD_COEFFICIENT", "OFF_MODEL_STATE_RULES"]

#: largest weighted squared distance (or ratio of two) a file may state: a residual of
#: ``SPREAD_RELATIVE`` power scales over a noise of ``NOISE_RELATIVE[0]`` of it, squared,
#: in each of up to 1000 ports
MAX_DISTANCE = 1e3 * (SPREAD_RELATIVE / NOISE_RELATIVE[0]) ** 2
#: largest magnitude of a coefficient of the log level of the remaining distances: the
#: level then varies at most e^12 times over the phase per harmonic (the measured fibre
#: coupler's largest coefficient is 1.5)
MAX_SPREAD_COEFFICIENT = 6.0


def _count_rule(what: str) -> tuple[FieldRule, FieldRule]:
    """A count of sweep readings: a whole number from ``low`` to the sweep's readings."""
    return (
        FieldRule(what, low=0.0, integer=True, scalar=True),
        FieldRule(what, high=1.0, scale="samples"),
    )


#: the rules of the ``off_model`` record's numbers (a calibration file's state), on top of
#: the checks :func:`basis_from_state` makes of their relations
OFF_MODEL_STATE_RULES = rule_table(
    {
        "off_model.readings": _count_rule("the sweep readings judged"),
        "off_model.above": _count_rule("sweep readings above the noise's median distance"),
        "off_model.beyond": _count_rule("sweep readings beyond the OFF_MODEL threshold"),
        "off_model.median": FieldRule(
            "the sweep's median cone distance", "", 0.0, MAX_DISTANCE, scalar=True
        ),
        "off_model.scale": FieldRule(
            "the OFF_MODEL threshold over the detector noise's",
            "",
            0.0,
            MAX_DISTANCE,
            open_low=True,
            scalar=True,
        ),
        "off_model.residual.harmonics": FieldRule(
            "the shared residual's harmonics", "", -1.0, MAX_HARMONICS, integer=True, scalar=True
        ),
        "off_model.residual.power_degree": FieldRule(
            "the shared residual's degree in the source power",
            "",
            0.0,
            MAX_POWER_DEGREE,
            integer=True,
            scalar=True,
        ),
        "off_model.residual.power_range": FieldRule(
            "a source power ratio", "", 1.0 / SPREAD_RELATIVE, SPREAD_RELATIVE
        ),
        "off_model.residual.coefficients_w": FieldRule(
            "a coefficient of the shared residual",
            "W",
            high=SPREAD_RELATIVE,
            scale="power_w",
            magnitude=True,
        ),
        "off_model.residual.readings": _count_rule("the sweep readings the residual is from"),
        "off_model.residual.median": FieldRule(
            "the median remaining distance", "", 0.0, MAX_DISTANCE, scalar=True
        ),
        "off_model.residual.spread_coefficients": FieldRule(
            "a coefficient of the remaining distances' log level",
            "",
            high=MAX_SPREAD_COEFFICIENT,
            magnitude=True,
        ),
    }
)

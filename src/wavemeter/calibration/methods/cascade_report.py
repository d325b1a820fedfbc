"""What a cascade declares for its report: its stages and hand-overs, and its wrong orders.

:func:`cascade_tables` turns ``diagnostics_["cascade"]`` into the tables of the stages
(FSR, ports, orders, standard deviation and error on the sweep) and the hand-overs (FSR
ratio and the largest the noise allows, margin, predicted and seen wrong orders);
:func:`order_errors` counts the wrong fringe orders of readings of known frequency
against those the cascade predicts and flags.
"""

from __future__ import annotations

import numpy as np

from ..contract.flags import ReadingFlag
from ..contract.summary import Check, Table
from ..files import fields
from .cascade_handover import handover_rules

__all__ = ["CASCADE_RECORD_RULES", "cascade_tables", "order_error_check", "order_errors"]


_number = fields.record_number
#: what the record the report presents (``diagnostics_["cascade"]``) holds, as a file's
#: diagnostics rules: a file whose record lacks them is refused on load, not in the report
#: (the count of stages is the cascade's ``_check_state``)
CASCADE_RECORD_RULES = fields.rule_table(
    {
        "cascade": fields.RecordRule("the cascade's record", "object"),
        "cascade.stages": fields.RecordRule("the stages' records", "list"),
        "cascade.stages.*.stage": _number("a stage", "", 1, integer=True),
        "cascade.stages.*.ports": fields.RecordRule("a stage's ports", "texts"),
        "cascade.stages.*.fsr_hz": _number("a stage's FSR", "Hz", 0.0),
        "cascade.stages.*.phase_order": _number("a phase order", "", 1, integer=True),
        "cascade.stages.*.map_order": _number("a map order", "", 0, integer=True),
        "cascade.stages.*.median_std_hz": _number("a median standard deviation", "Hz", 0.0),
        "cascade.stages.*.rms_hz": _number("an RMS error", "Hz", 0.0),
        "cascade.stages.*.z_std": _number("a z-score spread", "", 0.0),
        "cascade.handovers": fields.RecordRule("the hand-overs' records", "list"),
        **handover_rules("cascade.handovers"),
        "cascade.edge_margin_std": _number("the edge margin", "std"),
    }
)


def cascade_tables(record: dict, design_fsrs_hz, max_order_error: float) -> tuple[Table, ...]:
    """The stages and the hand-overs of a cascade, from its diagnostics record."""
    stages = Table(
        "stages",
        "stages",
        (
            "stage",
            "ports",
            "design FSR (GHz)",
            "fitted FSR (GHz)",
            "phase order P",
            "map order J",
            "median std (MHz)",
            "RMS error on the sweep (MHz)",
            "z-score spread",
        ),
        tuple(
            (
                stage["stage"],
                ", ".join(stage["ports"]),
                f"{design_fsrs_hz[index] / 1e9:.6g}",
                f"{stage['fsr_hz'] / 1e9:.9g}",
                stage["phase_order"],
                stage["map_order"],
                stage["median_std_hz"] / 1e6,
                stage["rms_hz"] / 1e6,
                stage["z_std"],
            )
            for index, stage in enumerate(record["stages"])
        ),
    )
    handovers = Table(
        "handovers",
        "hand-overs",
        (
            "hand-over",
            "FSR ratio",
            "largest usable ratio",
            "margin (std, median)",
            "worst margin (std)",
            "predicted wrong-order rate",
            "expected wrong on the sweep",
            "wrong on the sweep",
        ),
        tuple(
            (
                f"stage {handover['from_stage']} to {handover['to_stage']}",
                handover["ratio"],
                handover["largest_usable_ratio"],
                handover["margin_std"],
                handover["worst_margin_std"],
                f"{handover['predicted_rate']:.3g}",
                f"{handover['expected_wrong']:.3g}",
                handover["wrong_on_sweep"],
            )
            for handover in record["handovers"]
        ),
        "Each stage picks the fringe order of the next; a hand-over's margin is half the "
        "finer stage's FSR over the standard deviation of the two stages' difference, and "
        "the largest usable ratio the FSR ratio at which the sweep's noise would make the "
        f"wrong-order rate {max_order_error:g} (max_order_error, above which a reading is "
        "flagged ORDER_AMBIGUOUS). The coarsest stage's phase is unique "
        f"{record['edge_margin_std']:.3g} of its standard deviations beyond the band's ends "
        "(edge margin).",
    )
    return stages, handovers


def order_errors(calibration, powers_w, frequency_hz) -> dict:
    """Wrong fringe orders of a cascade on readings of known frequency, against those its
    ``order_error_probability`` predicts and those it flags ``ORDER_AMBIGUOUS``.

    Parameters
    ----------
    calibration : CascadeCalibrator
        A fitted cascade.
    powers_w : array_like, shape (N, n)
        Readings of every stage, in the unit of the calibration sweep.
    frequency_hz : array_like, shape (N,)
        Their true frequencies (Hz).

    Returns
    -------
    dict
        JSON-ready: ``readings``, ``wrong_orders`` (readings off by half the finest
        stage's local FSR or more), ``expected_wrong_orders`` (sum of the readings'
        ``order_error_probability``), ``flagged_order_ambiguous`` and
        ``wrong_orders_flagged`` (the wrong ones among those flagged).
    """
    found = calibration.read(powers_w)
    truth = np.asarray(frequency_hz, dtype=float)
    wrong = np.abs(found.frequency_hz[-1] - truth) >= 0.5 * calibration.fsr_hz_at(truth)
    flagged = (found.flags & ReadingFlag.ORDER_AMBIGUOUS) != 0
    return {
        "readings": int(truth.size),
        "wrong_orders": int(np.count_nonzero(wrong)),
        "expected_wrong_orders": float(np.sum(found.order_error_probability)),
        "flagged_order_ambiguous": int(np.count_nonzero(flagged)),
        "wrong_orders_flagged": int(np.count_nonzero(wrong & flagged)),
    }


def order_error_check(calibration, powers_w, frequency_hz) -> Check:
    """:func:`order_errors` as a check of the cascade, in words."""
    record = order_errors(calibration, powers_w, frequency_hz)
    text = (
        f"{record['wrong_orders']} of {record['readings']} readings off by half the finest "
        f"stage's FSR or more, {record['expected_wrong_orders']:.3g} expected from their "
        f"order_error_probability; {record['flagged_order_ambiguous']} flagged "
        f"ORDER_AMBIGUOUS ({record['wrong_orders_flagged']} of the wrong ones)."
    )
    return Check("order_errors", "wrong fringe orders", record, text)

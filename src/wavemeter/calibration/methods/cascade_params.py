"""A cascade's settings checked: the stages' design FSRs and the columns of each stage."""

from __future__ import annotations

import numpy as np

from ...exceptions import InputError, shown
from ...validation import check_positive

__all__ = ["design_fsrs_hz", "stage_columns"]


def design_fsrs_hz(values) -> tuple[float, ...]:
    """The design FSRs (Hz) of a cascade's stages, checked: two or more, positive,
    strictly decreasing (coarsest first)."""
    flat = isinstance(values, (list, tuple, np.ndarray)) and all(
        np.ndim(value) == 0 for value in values
    )
    if not flat or len(values) < 2:
        raise InputError(
            "fsr_hz must be the design FSRs of two or more stages (Hz, coarsest first), "
            f"got {shown(values)}",
            parameter="fsr_hz",
        )
    try:
        fsrs = tuple(check_positive("fsr_hz", value) for value in values)
    except InputError as exc:
        raise InputError(str(exc), parameter="fsr_hz") from exc
    if any(fine >= coarse for coarse, fine in zip(fsrs[:-1], fsrs[1:], strict=True)):
        raise InputError(
            f"fsr_hz must decrease from stage to stage (coarsest first), got {list(fsrs)}",
            parameter="fsr_hz",
        )
    return fsrs


def stage_columns(stage_ports, stages: int, ports: int | None) -> tuple[tuple[int, ...], ...]:
    """The columns of each of ``stages`` stages, from ``stage_ports`` (None: consecutive
    blocks of equal size), checked against ``ports`` columns (None: the setting alone)."""
    if stage_ports is None:
        if ports is None:
            return ()
        if ports % stages or ports // stages < 3:
            raise InputError(
                f"the readings have {ports} columns, which do not split into {stages} "
                "stages of 3 or more ports each: give stage_ports (the columns of each "
                "stage)",
                parameter="stage_ports",
            )
        size = ports // stages
        return tuple(tuple(range(k * size, (k + 1) * size)) for k in range(stages))
    given = stage_ports
    wrong = (
        f"stage_ports must list, for each of the {stages} stages, 3 or more column "
        f"indices (zero-based), got {given!r}"
    )
    if isinstance(given, (str, bytes)) or len(given) != stages:
        raise InputError(wrong, parameter="stage_ports")
    columns = []
    for block in given:
        if isinstance(block, (str, bytes)) or np.ndim(block) != 1 or len(block) < 3:
            raise InputError(wrong, parameter="stage_ports")
        if not all(
            isinstance(index, (int, np.integer)) and not isinstance(index, bool) and index >= 0
            for index in block
        ):
            raise InputError(wrong, parameter="stage_ports")
        columns.append(tuple(int(index) for index in block))
    flat = [index for block in columns for index in block]
    if len(set(flat)) != len(flat):
        raise InputError(
            f"stage_ports must give each column to one stage only, got {given!r}",
            parameter="stage_ports",
        )
    if ports is not None and sorted(flat) != list(range(ports)):
        missing = sorted(set(range(ports)) - set(flat))
        beyond = sorted(set(flat) - set(range(ports)))
        raise InputError(
            f"stage_ports must use every one of the {ports} columns once"
            + (f"; columns {missing} belong to no stage" if missing else "")
            + (f"; columns {beyond} do not exist" if beyond else "")
            + ": give each column to a stage, or leave it out of the readings",
            parameter="stage_ports",
        )
    return tuple(columns)

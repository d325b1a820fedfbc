"""The chip temperature of readings, for calibrations that need it.

A calibration that declares ``"temperature_k"`` in its ``requires`` (the thermal
calibration) needs the chip temperature of every reading: from a temperature column of the
file (found by name with its unit, e.g. ``temperature_K`` or ``Temp (C)``, or chosen with
``--temperature COL``; degrees Celsius are converted to K as the readers do) or one value
for the whole file (``--temperature-k T``, in K or with its unit: ``20C``). The commands
read that declaration, never the calibration's type. A calibration that does not use the
temperature refuses ``--temperature-k`` rather than ignore it.
"""

from __future__ import annotations

import click
import numpy as np

from ..exceptions import InputError
from ..jobs.readings import TEMPERATURE_COLUMN_NAMES, check_reading_options, needs_temperature
from ._params import TEMPERATURE

__all__ = [
    "needs_temperature",
    "temperature_k_option",
    "check_temperature_options",
    "missing_temperature",
    "reading_temperature_k",
    "TEMPERATURE_COLUMN_NAMES",
]


def temperature_k_option(help_text: str, *, multiple: bool = False):
    """The ``--temperature-k T`` option (K, or with its unit: ``293.15K``, ``20C``)."""
    return click.option(
        "--temperature-k",
        "temperature_k",
        type=TEMPERATURE,
        multiple=multiple,
        metavar="T",
        help=help_text,
    )


def check_temperature_options(calibration, what: str, *, column, given) -> None:
    """Before any reading: ``--temperature COL`` and ``--temperature-k`` are not both given,
    and ``--temperature-k`` only for a calibration that needs the temperature.

    Parameters
    ----------
    calibration : BaseCalibrator
        The calibration (fitted or not) the readings are for.
    what : str
        The calibration as the user named it (``"chip.wmcal.json"``, ``"--method learned"``).
    column : str or None
        The ``--temperature`` column.
    given : float, sequence of float, or None
        The ``--temperature-k`` value(s) (K); None or empty when not given.
    """
    given_any = given is not None and given != ()
    if column is not None and given_any:
        raise InputError(
            "--temperature COL and --temperature-k both give the chip temperature; give the "
            "column or the value, not both"
        )
    check_reading_options(calibration, name=what, temperature_k=given)


def missing_temperature(needed_by: str, source, remedy: str) -> InputError:
    """The error for readings without a temperature that a calibration needs.

    Parameters
    ----------
    needed_by : str
        Who needs it, as the start of the sentence (``"chip.wmcal.json is a thermal
        calibration: it"``).
    source : str or Path
        The file without a temperature column.
    remedy : str
        The options that give it.
    """
    return InputError(
        f"{needed_by} needs the chip temperature of each reading, and {source} has no "
        f"temperature column (looked for {TEMPERATURE_COLUMN_NAMES}); {remedy}"
    )


def reading_temperature_k(calibration, cal_path, table, given_k) -> np.ndarray | None:
    """Temperature (K) of each row of ``table`` for a calibration that needs it, else None.

    Parameters
    ----------
    calibration : BaseCalibrator
        The fitted calibration the readings are for.
    cal_path : str
        Its file, named in the error.
    table : Table
        The readings, read with a temperature column when there is one.
    given_k : float or None
        ``--temperature-k`` (K): the temperature of every row, instead of a column.

    Returns
    -------
    ndarray, shape (N,), K, or None

    Raises
    ------
    InputError
        When the calibration needs the temperature and neither is there.
    """
    if not needs_temperature(calibration):
        return None
    if given_k is not None:
        return np.full(table.n_rows, float(given_k))
    if table.temperature_k is None:
        raise missing_temperature(
            f"{cal_path} is a {calibration.method_label} calibration: it",
            table.source,
            "pass --temperature COL, or --temperature-k T for one temperature for the file",
        )
    return table.temperature_k

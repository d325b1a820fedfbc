"""The reference-cell options of ``wavemeter calibrate``: their types and declarations.

``--reference-column``, ``--lines``, ``--band``, ``--cell-pressure``,
``--cell-pressure-std`` and ``--axis-error`` set the fields of
:class:`wavemeter.jobs.CalibrateOptions` of the same meaning (:func:`cell_fields`).
"""

from __future__ import annotations

import re

import click

from ._params import BAND, FREQUENCY

__all__ = ["PRESSURE", "PressureParam", "cell_fields", "cell_options"]

#: pressure units a value may carry, in Pa
PRESSURE_UNITS_PA = {"pa": 1.0, "hpa": 100.0, "kpa": 1e3, "mbar": 100.0, "torr": 101325 / 760}
_PRESSURE_TEXT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z]*)\s*$")


class PressureParam(click.ParamType):
    """A pressure: ``13.3kPa``, ``100 mbar``, ``1 Torr``; a bare number is in Pa. Converts
    to Pa; ``allow_zero``: 0 allowed (an uncertainty), else it must be > 0."""

    name = "PRESSURE"

    def __init__(self, allow_zero: bool = False):
        self.allow_zero = allow_zero

    def convert(self, value, param, ctx):
        if isinstance(value, float):
            return value
        found = _PRESSURE_TEXT.match(str(value))
        unit = found.group(2).lower() if found else None
        if found is None or (unit and unit not in PRESSURE_UNITS_PA):
            self.fail(
                f"{value!r} is not a pressure: give a number and a unit of "
                f"{', '.join(['Pa', 'hPa', 'kPa', 'mbar', 'Torr'])} (13.3kPa)",
                param,
                ctx,
            )
        pressure_pa = float(found.group(1)) * PRESSURE_UNITS_PA[unit or "pa"]
        if pressure_pa < 0 or (pressure_pa == 0 and not self.allow_zero):
            self.fail(f"{value}: must be {'>= 0' if self.allow_zero else '> 0'}", param, ctx)
        return pressure_pa


PRESSURE = PressureParam()


def cell_options(command):
    """Decorate ``calibrate`` with the reference-cell options."""
    options = [
        click.option(
            "--reference-column",
            metavar="COL",
            help="The sweep file's column with a reference gas cell's transmission, "
            "recorded beside the ports; with --lines the calibration is absolute: the "
            "laser's axis is corrected from the cell's lines.",
        ),
        click.option(
            "--lines",
            "reference_lines",
            metavar="FILE",
            type=click.Path(dir_okay=False),
            help="The cell's line table: CSV with the header label,center_hz,std_hz (or "
            "center_nm; optional pressure_shift_hz_per_pa), '#' lines its source. No table "
            "ships with wavemeter: give your cell's certified lines.",
        ),
        click.option(
            "--band",
            "band_hz",
            type=BAND,
            metavar="LOW:HIGH",
            help="The band the sweep covers (1527nm:1565nm, 191THz:196THz): the cell's lines "
            "are identified among the table's there. With it, a sweep file without a "
            "frequency column is self-calibrated from the lines.",
        ),
        click.option(
            "--cell-pressure",
            "reference_pressure_pa",
            type=PRESSURE,
            help="The cell's pressure (13.3kPa), for a table of zero-pressure centres with "
            "pressure shifts.",
        ),
        click.option(
            "--cell-pressure-std",
            "reference_pressure_std_pa",
            type=PressureParam(allow_zero=True),
            help="Standard uncertainty of --cell-pressure (0.4kPa). Default 0.",
        ),
        click.option(
            "--axis-error",
            "axis_error_hz",
            type=FREQUENCY,
            metavar="FREQUENCY",
            help="A bound on the recorded axis's error (1.3GHz): below a quarter of the line "
            "spacing each line is the nearest table line; default: identified by the "
            "pattern of spacings.",
        ),
    ]
    for option in reversed(options):
        command = option(command)
    return command


def cell_fields(options: dict) -> dict:
    """The :class:`~wavemeter.jobs.CalibrateOptions` fields of the cell options given."""
    std = options.get("reference_pressure_std_pa")
    return {
        "reference_column": options.get("reference_column"),
        "reference_lines": options.get("reference_lines"),
        "band_hz": options.get("band_hz"),
        "reference_pressure_pa": options.get("reference_pressure_pa"),
        "reference_pressure_std_pa": 0.0 if std is None else std,
        "axis_error_hz": options.get("axis_error_hz"),
    }

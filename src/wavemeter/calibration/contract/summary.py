"""Fit reports: what a fitted calibrator learned, with standard errors where known.

:meth:`wavemeter.calibration.contract.base.BaseCalibrator.summary` returns a :class:`FitReport`,
in the spirit of lmfit's fit report: the values with their standard errors and units,
the settings, the sweep it was fitted on and the diagnostics (the sweep's own FSR, every
port's fringe, warnings). ``report.as_dict()`` is JSON-ready, ``str(report)`` (or
``report.text``) the aligned text the command line prints.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ...units import SPEED_OF_LIGHT_M_S, frequency_text
from .summary_lines import (
    LABEL_WIDTH,
    diagnostics_lines,
    line,
    samples_text,
    settings_text,
)

__all__ = ["Check", "FitReport", "FitValue", "LABEL_WIDTH", "Table", "value_text"]


@dataclass(frozen=True)
class FitValue:
    """One learned value with its standard error (None when the method gives none).

    Attributes
    ----------
    value : float
    stderr : float or None
    unit : str
        SI unit of ``value`` and ``stderr`` (empty for pure numbers).
    label : str
        How people read its name (``"group-delay dispersion"``); empty: the key's words.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> fsr = cal.summary().values["fsr_hz"]
    >>> fsr.unit
    'Hz'

    The fitted FSR's standard error (4 MHz) covers its distance to the true FSR (4.8 MHz):

    >>> print(f"{fsr.value / 1e9:.4f} GHz +- {fsr.stderr / 1e6:.1f} MHz")
    51.5076 GHz +- 4.1 MHz
    >>> print(f"true {device.true_fsr_hz / 1e9:.4f} GHz")
    true 51.5029 GHz
    """

    value: float
    stderr: float | None = None
    unit: str = ""
    label: str = ""

    def to_dict(self) -> dict:
        return {"value": self.value, "stderr": self.stderr, "unit": self.unit, "label": self.label}


@dataclass(frozen=True)
class Table:
    """A table a calibration adds to its description or evaluation (stages, hand-overs,
    candidate orders, windows), ready to render.

    Attributes
    ----------
    name : str
        Its key (``"handovers"``).
    title : str
        Its heading.
    columns : tuple of str
        Column headings, the display unit in brackets.
    rows : tuple of tuple
        Cells: text, integers, or floats in the column's display unit.
    text : str
        What the table means, in a sentence or two.

    Examples
    --------
    >>> from wavemeter.calibration import Table
    >>> stages = Table(
    ...     name="stages",
    ...     title="Stages",
    ...     columns=("stage", "FSR [GHz]", "noise [MHz]"),
    ...     rows=((1, 514.0, 641.0), (2, 50.2, 58.0)),
    ...     text="The cascade's stages, coarsest first.",
    ... )
    >>> dict(zip(stages.columns, stages.rows[1]))
    {'stage': 2, 'FSR [GHz]': 50.2, 'noise [MHz]': 58.0}
    """

    name: str
    title: str
    columns: tuple
    rows: tuple
    text: str = ""

    def as_dict(self) -> dict:
        return {
            "name": self.name,
            "title": self.title,
            "columns": list(self.columns),
            "rows": [list(row) for row in self.rows],
            "text": self.text,
        }

    def cell_text(self, cell) -> str:
        """A cell as shown: floats with four significant digits."""
        if isinstance(cell, float):
            return f"{cell:.4g}"
        return str(cell)

    def text_lines(self) -> list[str]:
        """The table as aligned text: its title, the column headings, one line per row,
        then its text."""
        cells = [list(self.columns)]
        cells += [[self.cell_text(cell) for cell in row] for row in self.rows]
        widths = [max(len(row[k]) for row in cells) for k in range(len(self.columns))]
        lines = [f"{self.title}:"]
        lines += [
            "  " + "  ".join(cell.rjust(width) for cell, width in zip(row, widths, strict=True))
            for row in cells
        ]
        if self.text:
            lines.append(f"  {self.text}")
        return lines


@dataclass(frozen=True)
class Check:
    """A check a calibration makes of itself on readings of known frequency, beyond the
    frequency error every evaluation reports (a set's maps on the neighbouring FSRs, a
    cascade's wrong fringe orders).

    Attributes
    ----------
    name : str
        Its key in JSON output (``"adjacent"``, ``"order_errors"``).
    title : str
        Its heading.
    record : dict
        The numbers, JSON-ready.
    text : str
        What they say, in a sentence or two.
    table : Table or None
        The numbers in rows, where there are many.

    Examples
    --------
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(800, span_fsr=4)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> cal_set = wm.CalibrationSet(fsr_hz=50e9).fit(powers, f_hz)
    >>> test = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=2)
    >>> checks = cal_set.evaluation_checks(test, f_hz)  # a set checks its maps on the neighbours
    >>> [(check.name, check.title) for check in checks]
    [('adjacent', 'Maps applied to the neighbouring FSRs ([1], Fig. 9)')]
    """

    name: str
    title: str
    record: dict
    text: str = ""
    table: Table | None = None


def value_text(value: FitValue) -> str:
    """A value with its standard error in its unit: frequencies (``Hz``, ``Hz/K``) in the
    unit that suits them, delays in ps, other numbers with six significant digits."""
    unit = value.unit
    if unit.startswith("Hz"):
        rest = unit[2:]
        text = f"{frequency_text(value.value)}{rest}"
        if value.stderr is not None:
            text += f" +- {frequency_text(value.stderr, 3)}{rest}"
        return text
    if unit == "s" and abs(value.value) < 1e-6:
        text = f"{value.value * 1e12:.6f} ps"
        if value.stderr is not None:
            text += f" +- {value.stderr * 1e12:.3g} ps"
        return text
    text = f"{value.value:.6g}"
    if value.stderr is not None:
        text += f" +- {value.stderr:.3g}"
    return f"{text} {unit}".rstrip()


def _frequency_with_error(value: FitValue) -> str:
    text = f"{value.value / 1e9:.6f} GHz"
    if value.stderr is not None:
        text += f" +- {frequency_text(value.stderr, 3)}"
    return text


@dataclass(frozen=True)
class FitReport:
    """What a fitted calibrator learned (see :meth:`BaseCalibrator.summary`).

    Attributes
    ----------
    method : str
        File tag of the class.
    method_label : str
        The method as people read it (e.g. ``"learned per FSR"``).
    settings : dict
        Settings given to ``__init__``, JSON-ready (retrieval, bracket, window, ...).
    values : dict of str to FitValue
        Learned values by name: ``fsr_hz``, ``design_fsr_hz``, ``center_hz``,
        ``calibration_rms_hz`` for every method; ``noise_std_w``, ``delay_s`` and others
        where the method has them.
    ports : tuple of str
        Port names.
    samples : int
        Calibration readings.
    span_hz : (float, float)
        Lowest and highest calibration frequency (Hz).
    diagnostics : dict
        The calibrator's ``diagnostics_`` (sweep FSR estimate, port health, warnings).
    windows : tuple of FitReport
        One report per part of a composite (a set's windows, a cascade's stages);
        empty otherwise.
    windows_are : {"windows", "stages"}
        What ``windows`` holds: a set's windows (numbered from 0) or a cascade's stages
        (numbered from 1, coarsest first).
    tables : tuple of Table
        What the method adds in tables (a cascade's stages and hand-overs, the candidate
        orders of a wide band).
    notes : tuple of str
        What the method adds in words (the calibrated temperatures and what they resolve).

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> report = cal.summary()  # what the calibration learned, as every command shows it
    >>> report.method, report.samples, report.ports
    ('learned', 200, ('p1', 'p2', 'p3'))
    >>> list(report.values)[:4]
    ['fsr_hz', 'design_fsr_hz', 'center_hz', 'calibration_rms_hz']
    >>> fsr = report.values["fsr_hz"]
    >>> print(f"FSR {fsr.value / 1e9:.4f} GHz +- {fsr.stderr / 1e6:.1f} MHz")
    FSR 51.5076 GHz +- 4.1 MHz
    >>> rms = report.values["calibration_rms_hz"]
    >>> print(f"{rms.value / 1e6:.1f} MHz RMS on the sweep")
    13.5 MHz RMS on the sweep
    """

    method: str
    method_label: str
    settings: dict
    values: dict
    ports: tuple
    samples: int
    span_hz: tuple
    diagnostics: dict = field(default_factory=dict)
    windows: tuple = ()
    windows_are: str = "windows"
    tables: tuple = ()
    notes: tuple = ()

    def __getitem__(self, name: str) -> FitValue:
        return self.values[name]

    def as_dict(self) -> dict:
        """JSON-ready form."""
        return {
            "method": self.method,
            "method_label": self.method_label,
            "settings": self.settings,
            "values": {name: value.to_dict() for name, value in self.values.items()},
            "ports": list(self.ports),
            "samples": self.samples,
            "span_hz": list(self.span_hz),
            "diagnostics": self.diagnostics,
            "windows": [window.as_dict() for window in self.windows],
            "windows_are": self.windows_are,
            "tables": [table.as_dict() for table in self.tables],
            "notes": list(self.notes),
        }

    @property
    def text(self) -> str:
        """Aligned text: one quantity per line, label column ``LABEL_WIDTH`` wide."""
        values = dict(self.values)
        fsr, design = values.pop("fsr_hz"), values.pop("design_fsr_hz")
        center = values.pop("center_hz").value
        rms = values.pop("calibration_rms_hz").value
        low, high = self.span_hz
        lines = [
            line("method", self.method_label),
            line("settings", settings_text(self.settings)),
            line("FSR", f"{_frequency_with_error(fsr)} (design {design.value / 1e9:g} GHz)"),
            line("centre", f"{center / 1e12:.6f} THz ({SPEED_OF_LIGHT_M_S / center * 1e9:.4f} nm)"),
            line(
                "span",
                f"{low / 1e12:.6f} to {high / 1e12:.6f} THz ({(high - low) / 1e9:.4f} GHz, "
                f"{(high - low) / fsr.value:.3g} FSR)",
            ),
            line("ports", f"{len(self.ports)}: {', '.join(self.ports)}"),
            line("samples", samples_text(self.samples, self.diagnostics or {})),
            line("calibration RMS", f"{rms / 1e6:.4f} MHz"),
        ]
        noise = values.pop("noise_std_w", None)
        if noise is not None:
            lines.append(line("noise estimate", f"{noise.value:.4g} W (calibration residual)"))
        delay = values.pop("delay_s", None)
        if delay is not None:
            error = "" if delay.stderr is None else f" +- {delay.stderr * 1e12:.3g} ps"
            lines.append(line("delay", f"{delay.value * 1e12:.6f} ps{error}"))
        for name, value in values.items():
            lines.append(line(value.label or name.replace("_", " "), value_text(value)))
        lines += [line("", note) for note in self.notes]
        if self.windows:
            lines.append(line(self.windows_are, "centre THz      FSR GHz   samples   RMS MHz"))
            first = 1 if self.windows_are == "stages" else 0
            for index, window in enumerate(self.windows, start=first):
                lines.append(
                    f"  {index:<14} {window['center_hz'].value / 1e12:>10.6f} "
                    f"{window['fsr_hz'].value / 1e9:>12.6f} {window.samples:>9} "
                    f"{window['calibration_rms_hz'].value / 1e6:>9.4f}"
                )
        for table in self.tables:
            lines += table.text_lines()
        lines += diagnostics_lines(self.diagnostics)
        if not self.diagnostics:
            lines.append(line("diagnostics", "none recorded (a file of wavemeter 0.1)"))
        elif not self.diagnostics.get("warnings"):
            lines.append(line("warnings", "none"))
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.text

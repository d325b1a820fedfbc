"""`wavemeter simulate`: the recordings of a :class:`wavemeter.simulation.Scenario`, written.

The command parses its options (:mod:`._simulate_options`; each option's name in Python is
the scenario's field, and an option left out is a field left at its default) into a
scenario, which checks them and simulates; the command writes its tables (the sweep, the
``--test`` and ``--laser`` files), then prints what it simulated
(:mod:`._simulate_lines`). The scenario's errors name its fields; they are printed under
the options' names.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import re
from pathlib import Path

import click
import numpy as np
from click.core import ParameterSource

from ..exceptions import InputError
from ..io import write_table
from ..progress import busy, progress_bar
from ..simulation import CELL_PRESETS, Scenario, simulated_band_lines
from ..units import SENTINEL_DBM
from ._common import FORCE, FORMAT, QUIET, note, output_format, printable, say
from ._simulate_lines import summary_lines
from ._simulate_options import PLATFORMS, SPECTRAL_PLATFORMS, scenario_options
from ._streams import is_stdio

__all__ = ["simulate", "command", "PLATFORMS", "SPECTRAL_PLATFORMS"]

#: a field name in a message: lower-case words joined by ``_``
_FIELD_NAME = re.compile(r"\b[a-z0-9]+(?:_[a-z0-9]+)+\b")


@contextlib.contextmanager
def _in_option_words(command):
    """The scenario's errors in the command's words: a field name becomes its option
    (``dark_offset_w`` -> ``--dark-offset``; a field without ``_`` only where the message
    starts with it, as ``ports must be ...``), and the option of the field at fault is
    named when the message does not name it. Other errors pass as they are."""
    fields = {item.name for item in dataclasses.fields(Scenario) if item.init}
    options = {param.name: param.opts[0] for param in command.params if param.name in fields}
    try:
        yield
    except InputError as exc:
        text, parameter = str(exc), exc.parameter
        named = _FIELD_NAME.sub(lambda found: options.get(found[0], found[0]), text)
        if parameter not in options:
            if named == text:
                raise
            raise type(exc)(named, parameter=parameter) from exc
        if named.startswith(f"{parameter} "):
            named = options[parameter] + named[len(parameter) :]
        if options[parameter] not in named:
            named += f" (use {options[parameter]})"
        raise type(exc)(named) from exc


def _same_file(first: str, second: str) -> bool:
    if is_stdio(first) or is_stdio(second):
        return is_stdio(first) and is_stdio(second)
    return os.path.realpath(first) == os.path.realpath(second)


def _targets(out_path: str, scenario: Scenario, outs: dict) -> dict[str, str]:
    """The files to write, by table: the sweep, and with ``--test``, ``--laser`` and
    ``--dark`` their files (``outs``; default: OUT with ``-test``, ``-laser`` or ``-dark``
    before the extension), all distinct."""
    targets = {"sweep": out_path}
    for name, rows in (("test", scenario.test), ("laser", scenario.laser), ("dark", scenario.dark)):
        path = outs[name]
        if not rows:
            continue
        if path is None:
            if is_stdio(out_path):
                raise InputError(
                    f"with -o - (stdout) and --{name}, name the {name} file with --{name}-out"
                )
            path = str(Path(out_path).with_stem(f"{Path(out_path).stem}-{name}"))
        for other, other_path in targets.items():
            if _same_file(path, other_path):
                raise InputError(
                    f"--{name}-out {path} is the {other} file too: give two different files"
                )
        targets[name] = path
    return targets


def _lines_target(out_path: str, scenario: Scenario, force: bool) -> str | None:
    """Where the table of a simulated band goes: OUT with ``-lines.csv``; None for a cell
    of the user's table or none."""
    if scenario.reference_cell not in CELL_PRESETS:
        return None
    if is_stdio(out_path):
        raise InputError("--reference-cell of a simulated band writes its table: give -o FILE")
    path = str(Path(out_path).with_name(f"{Path(out_path).stem}-lines.csv"))
    if Path(path).exists() and not force:
        raise InputError(f"{path} exists: the band's table would replace it; use --force")
    return path


@click.command()
@scenario_options
@FORMAT
@FORCE
@QUIET
def simulate(
    out_path, test_out, laser_out, dark_out, no_monitor, file_format, force, quiet, **fields
):
    """Simulate a sweep of a Table 1 device (paper Section III) and write it to a file.

    Powers take a unit (1mW, 5e-7W, -30dBm) and frequencies too (50GHz); bare numbers are
    SI (W, Hz). Every file is checked before anything is simulated; an existing file is
    replaced only with --force. In Python: wavemeter.simulation.Scenario, whose fields
    are these options.

    Fault options (--dark-offset, --port-noise, --dispersion, --power-drift, --thermal-drift)
    model real hardware. The detectors and the chip's dispersion are the device's: they
    reach the --test, --laser and --dark files too. The drifts happen during the
    calibration sweep: the other files have none. The power drift has a random stream of
    its own, so the noise is the same as without it. A monitor column is written when the
    source power varies (--power-fluctuation or --power-drift) and records the true source
    power, in every file unless --no-monitor.

    A thermal device (--platform) is recorded at --temperature-k, or during --ramp-k
    (with --repeat sweeps in a row, so that temperature and frequency do not change
    together); every file gets a temperature_k column. Runs at several temperatures with
    one --seed simulate one device, each with noise of its own.

    A wide-band device (--spectral sin, or --coupler-slope and --responsivity-slope alone)
    has an output coupler and receivers that change slowly with frequency, drawn from
    --seed, and the platform's dispersion; a C-band sweep is --span-fsr 88.

    A cascade (--cascade 5THz,500GHz,50GHz) is Table 1 stages of decreasing FSR with
    --ports ports each, fed by one source (--power, split equally), swept evenly over
    --band (default the C band, 191-195.4 THz); the test readings are uniform over the
    band. Its port columns p11, p12, .., p21, .. name stage and port. With --spectral sin
    every stage gets the platform's slopes and the dispersion of its delay. The single
    device's FSR, span, detector and thermal faults are not simulated for a cascade.

    A sweep as a laser records it (--sweep-axis) with a reference gas cell beside the
    ports (--reference-cell) is what `calibrate --reference-column cell_transmission
    --lines FILE` makes absolute; the true frequencies are written for evaluation only.

    A laser record (--laser N) is N readings of a laser with white, flicker and
    random-walk FM and a drift (--white-fm, --flicker-fm, --random-walk-fm, --laser-drift)
    at --laser-rate, from the device's centre: `wavemeter noise` measures them with the
    calibration of the sweep and finds those levels. Dark readings (--dark N) are the
    device read with the source off, its detectors' dark offset and noise, for
    `wavemeter calibrate --dark`.

    \b
    Example:
      wavemeter simulate -o hybrid.csv --ports 4 --seed 2 --test 2000
      wavemeter simulate -o lab.csv --write-axis-unit nm --write-power-unit dBm --noise 20nW
      wavemeter simulate -o faulty.csv --dark-offset 2uW --power-drift 0.05 --test 2000 \\
          --dark 500
      for t in 292 293.5 295; do \\
          wavemeter simulate -o s$t.csv --platform sin --temperature-k $t; done
      wavemeter simulate -o ramp.csv --platform sin --ramp-k 292:295 --repeat 5 --test 2000
      wavemeter simulate -o band.csv --spectral sin --span-fsr 24 --samples 24000 \\
          --test 2000 --laser 1000
      wavemeter simulate -o cband.csv --cascade 5THz,500GHz,50GHz --spectral sin \\
          --samples 8000 --test 2000
      wavemeter simulate -o chip.csv --laser 65536 --laser-out laser.csv \\
          --white-fm 1.6e8 --laser-drift 1e9
      wavemeter simulate -o today.csv --laser 1000 --laser-out line.csv \\
          --laser-frequency 193.4THz
      wavemeter simulate -o s294.csv --platform sin --temperature-k 21C \\
          --laser 1000 --laser-out line21.csv --laser-frequency 193.4THz
      mkdir wafer7 && for s in 1 2; do wavemeter simulate -o wafer7/die$s.csv --seed $s; done
      wavemeter simulate -o cell.csv --span-fsr 20 --samples 8000 --sweep-axis tls-spec \\
          --reference-cell hcn-like
    """
    context = click.get_current_context()
    given = {
        name: value
        for name, value in fields.items()
        if context.get_parameter_source(name) is not ParameterSource.DEFAULT
    }
    with _in_option_words(context.command):
        scenario = Scenario(monitor=not no_monitor, **given)
    targets = _targets(out_path, scenario, {"test": test_out, "laser": laser_out, "dark": dark_out})
    lines_path = _lines_target(out_path, scenario, force)
    formats = {
        name: output_format(path, file_format, force=force) for name, path in targets.items()
    }
    to_stderr = any(is_stdio(path) for path in targets.values())

    def progress(table, total, unit):
        return progress_bar(
            printable(f"simulating {targets[table]}"), total, quiet=quiet, unit=unit
        )

    with _in_option_words(context.command):  # everything is simulated before anything is written
        sweep, test = scenario.tables(progress)
        tables = {
            "sweep": sweep,
            "test": test,
            "laser": scenario.laser_table(progress),
            "dark": scenario.dark_table(progress),
        }
    for name, path in targets.items():
        columns = tables[name]
        with busy(printable(f"writing {path}"), quiet=quiet):
            write_table(path, columns, formats[name])
        rows = len(next(iter(columns.values())))
        written = "stdout" if is_stdio(path) else path
        say(quiet, f"wrote {written} ({rows} rows: {', '.join(columns)})", err=to_stderr)
        codes = sum(int(np.count_nonzero(values == SENTINEL_DBM)) for values in columns.values())
        if scenario.power_unit == "dBm" and codes:
            note(
                quiet,
                f"{codes} reading(s) at or below 0 W (noise at a fringe null) are written as "
                f"the {SENTINEL_DBM:g} dBm no-reading code; read {path} with --drop-invalid, "
                "or simulate with a lower --noise",
            )
    if lines_path is not None:  # the simulated band's table, for calibrate --lines
        simulated_band_lines(scenario.reference_cell)[0].to_csv(lines_path)
        say(quiet, f"wrote {lines_path} (the SIMULATED {scenario.reference_cell} lines)")
    for line in summary_lines(scenario, sweep):
        say(quiet, line, err=to_stderr)


command = simulate

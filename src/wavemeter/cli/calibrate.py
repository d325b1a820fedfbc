"""`wavemeter calibrate`: learn a calibration from a sweep file (several for a thermal one).

Dark readings (``--dark FILE`` averaged per port, or ``--dark-w``) are subtracted from the
sweep and kept in the calibration. With ``--strict`` a :class:`CalibrationWarning` of the
fit is an error: nothing is written and the exit code is 3.

A method that needs the chip temperature of each reading (``"temperature_k"`` in its
calibrator's ``requires``: ``--method thermal``) is fitted on one or more sweep files,
concatenated in the order given, with the temperature from each file's temperature column
or ``--temperature-k`` once per file; the files must have the same ports and all or none a
power monitor. The other methods take one sweep file (one chip state).

Options that belong to one method alone: ``--phase-order`` and ``--map-order`` (fixed
orders of ``--method wideband``, otherwise chosen by cross-validation), a list of FSRs,
``--stage-ports`` and ``--max-order-error`` (``--method cascade``: stages of decreasing
FSR, coarsest first, from one sweep over the band).

The learned method (without ``--per-fsr``) reads its sweep in chunks, with a progress bar,
in memory bounded by the chunk (:func:`wavemeter.jobs.calibrate.fit_sweep_chunks`): the
calibration is the one a whole read gives. The other methods read the whole sweep. What
each option does: the command reference and the user guide's sweep, temperature,
wide-band and cascade pages.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass

import click
import numpy as np
from click.core import ParameterSource

from ..calibration.fitting.sweep import value_range
from ..exceptions import InputError, recorded_calibration_warnings
from ..io import ColumnRequest, iter_readings, port_key
from ..io.streaming import CHUNK_ROWS
from ..jobs.calibrate import SweepRead, build_calibrator, fit_sweep_chunks
from ..progress import busy, progress_bar
from ._common import (
    FORCE,
    PORT_PHASES,
    QUIET,
    about,
    check_calibration_output,
    column_options,
    column_request,
    frequency_text,
    note,
    out_option,
    port_phases_rad,
    printable,
    read,
    say,
    setting,
)
from ._params import FSRS, MAP_ORDER, OFFSETS, PHASE_ORDER, STAGE_PORTS
from ._streams import STDIN_LABEL, is_stdio, output_path
from ._temperature import (
    check_temperature_options,
    missing_temperature,
    needs_temperature,
    temperature_k_option,
)
from .app import WarningsRefused

#: sensor noise of the chip temperature a thermal calibration assumes by default (K)
DEFAULT_TEMPERATURE_STD_K = 1e-3
#: options of the wide-band method alone: option name -> its parameter
WIDEBAND_OPTIONS = {"--phase-order": "phase_order", "--map-order": "map_order"}
#: options of the cascade alone: option name -> its parameter
CASCADE_OPTIONS = {"--stage-ports": "stage_ports", "--max-order-error": "max_order_error"}


@contextlib.contextmanager
def _refused_if(strict: bool):
    """With ``strict``, the block's :class:`CalibrationWarning` s are collected instead of
    shown and raised together after it as :class:`WarningsRefused`; other warnings are
    shown as usual."""
    if not strict:
        yield
        return
    with recorded_calibration_warnings() as refused:
        yield
    if refused:
        raise WarningsRefused(refused, "--strict: no calibration written")


def _port_list(table) -> str:
    return ", ".join(table.port_names)


def _dark_w(options: dict, request, sweep_table) -> np.ndarray | None:
    """Per-port dark readings (W) from ``--dark FILE`` (averaged) or ``--dark-w``, checked
    against the sweep's ports (``sweep_table``: anything with ``source`` and
    ``port_names``); None without either."""
    path, values = options["dark_file"], options["dark_w"]
    ports = len(sweep_table.port_names)
    expected = f"{sweep_table.source} has {ports} ports ({_port_list(sweep_table)})"
    if values is not None:
        if len(values) != ports:
            raise InputError(
                f"--dark-w gives {len(values)} value(s) but {expected}; give one offset per "
                "port, in that order",
                parameter="dark_w",
            )
        return np.array(values)
    if path is None:
        return None
    ports_only = ColumnRequest(
        ports=request.ports,
        power_unit=request.power_unit,
        delimiter=request.delimiter,
        decimal=request.decimal,
    )
    dark = read(
        path,
        ports_only,
        need_x=False,
        drop_invalid=options["drop_invalid"],
        quiet=options["quiet"],
        light=False,
    ).valid_only()
    names = [port_key(name) for name in dark.port_names]
    if len(names) != ports or (
        request.ports is None and names != [port_key(name) for name in sweep_table.port_names]
    ):
        raise InputError(
            f"{dark.source} has ports {_port_list(dark)} but {expected}; the dark readings "
            "need the sweep's ports: pass --ports with the columns of both files in order"
        )
    if dark.n_rows == 0:
        raise InputError(f"{dark.source}: no valid dark readings to average")
    return dark.powers_w.mean(axis=0)


def _fsr_list_text(fsrs_hz) -> str:
    return ", ".join(frequency_text(value) for value in fsrs_hz)


def _design_fsr(options: dict):
    """The design FSR of the method: one (Hz), or a cascade's, coarsest first (tuple, Hz;
    the C-band cascade's 5 THz / 500 GHz / 50 GHz when ``--fsr`` is not given)."""
    fsrs, method = options["fsr"], options["method"]
    if method != "cascade":
        if len(fsrs) != 1:
            raise InputError(
                f"--fsr gives {len(fsrs)} FSRs ({_fsr_list_text(fsrs)}) but --method {method} "
                "calibrates one interferometer: give its one design FSR, or --method cascade "
                "for stages of decreasing FSR"
            )
        return fsrs[0]
    if not _given("fsr"):
        from ..calibration.methods.cascade import DEFAULT_FSRS_HZ

        return DEFAULT_FSRS_HZ
    if len(fsrs) < 2:
        raise InputError(
            f"--method cascade needs the design FSR of every stage, two or more, coarsest "
            f"first (e.g. --fsr 5THz,500GHz,50GHz); got one ({_fsr_list_text(fsrs)})"
        )
    if any(fine >= coarse for coarse, fine in zip(fsrs[:-1], fsrs[1:], strict=True)):
        raise InputError(
            f"--fsr {_fsr_list_text(fsrs)}: the FSRs of a cascade must decrease from stage to "
            "stage; list them coarsest first (e.g. --fsr 5THz,500GHz,50GHz)"
        )
    return fsrs


def _calibrator(options: dict, phases):
    """The unfitted calibrator the options ask for (a calibration set with ``--per-fsr``)."""
    from ..calibration.methods.set import CalibrationSet

    tolerance, method = options["fsr_tolerance"], options["method"]
    retrieval = options["retrieval"]
    if method == "conventional" and retrieval != "pinv":
        raise InputError(
            f"--retrieval {retrieval} needs --method learned, thermal, wideband or cascade, "
            f"got --method {method}"
        )
    for option, name in WIDEBAND_OPTIONS.items():
        if method != "wideband" and _given(name):
            raise InputError(
                f"{option} is an order of the wide-band model (--method wideband); --method "
                f"{method} has no such order: leave {option} out, or add --method wideband"
            )
    for option, name in CASCADE_OPTIONS.items():
        if method != "cascade" and _given(name):
            raise InputError(
                f"{option} is a setting of a cascade of stages (--method cascade); --method "
                f"{method} calibrates one interferometer: leave {option} out, or add --method "
                "cascade"
            )
    fsr = _design_fsr(options)
    if method == "cascade" and options["stage_ports"] is not None:
        _check_stage_groups(options["stage_ports"], fsr)
    settings = {
        "learned": {},
        "wideband": {"phase_order": options["phase_order"], "map_order": options["map_order"]},
        "cascade": {"max_order_error": options["max_order_error"]},
        "thermal": {"temperature_std_k": options["temperature_std_k"]},
        "conventional": {"port_phases_rad": phases},
    }[method]
    if method != "conventional":
        settings |= {"fsr_tolerance": tolerance, "retrieval": retrieval}
    calibrator = build_calibrator(method, fsr_hz=fsr, **settings)
    if method != "thermal" and _given("temperature_std_k"):
        raise InputError(
            f"--temperature-std-k is the temperature sensor noise of a thermal calibration "
            f"(--method thermal); --method {method} does not use it"
        )
    if options["per_fsr"]:
        if method in ("wideband", "cascade"):
            raise InputError(
                f"--per-fsr calibrates each FSR on its own, --method {method} the whole band "
                "at once: choose one of them"
            )
        if calibrator.requires:
            raise InputError(
                f"--per-fsr calibrates each FSR with a method that needs nothing but the "
                f"readings; --method {method} also needs {', '.join(sorted(calibrator.requires))}"
                ": calibrate one FSR, or leave out --per-fsr"
            )
        calibrator = CalibrationSet(fsr, tolerance, window=calibrator)
    return calibrator


def _given(name: str) -> bool:
    """Whether the option ``name`` was given on the command line (not its default)."""
    source = click.get_current_context().get_parameter_source(name)
    return source not in (None, ParameterSource.DEFAULT)


@dataclass(frozen=True)
class _Sweeps:
    """The sweep files of one calibration, concatenated in the order given.

    Attributes
    ----------
    tables : tuple of Table
        One per file read whole, valid rows only, rows in file order; empty for a sweep
        read in chunks.
    records : tuple of SweepRead
        What reading each file found (columns, rows).
    temperature_k : ndarray, shape (N,), or None
        Chip temperature (K) of every row, for a calibrator that needs it.
    given_k : tuple of float
        ``--temperature-k`` of each file (K); empty when the temperature came from columns.
    """

    tables: tuple
    records: tuple
    temperature_k: np.ndarray | None
    given_k: tuple

    @property
    def first(self) -> SweepRead:
        return self.records[0]

    @property
    def label(self) -> str:
        """The files, as messages name them."""
        return ", ".join(str(record.source) for record in self.records)

    @property
    def n_rows(self) -> int:
        return sum(record.n_rows for record in self.records)

    @property
    def powers_w(self) -> np.ndarray:
        return np.concatenate([table.powers_w for table in self.tables])

    @property
    def x_hz(self) -> np.ndarray:
        return np.concatenate([table.x_hz for table in self.tables])

    @property
    def monitor_w(self) -> np.ndarray | None:
        if self.first.monitor_column is None:
            return None
        return np.concatenate([table.monitor_w for table in self.tables])

    @property
    def temperature_range_k(self) -> list[float] | None:
        """Lowest and highest chip temperature (K): of every row for a calibrator that
        needs it, else of the files' temperature columns when every file has one."""
        if self.temperature_k is not None:
            return value_range(self.temperature_k)
        ranges = [record.temperature_range_k for record in self.records]
        if any(extent is None for extent in ranges):
            return None
        return [min(low for low, _ in ranges), max(high for _, high in ranges)]


def _record(table) -> SweepRead:
    """What a sweep read whole found (its valid rows), as a read in chunks reports it."""
    return SweepRead(
        source=table.source,
        x_column=table.x_column,
        x_unit=table.x_unit,
        port_names=tuple(table.port_names),
        port_units=tuple(table.port_units),
        monitor_column=table.monitor_column,
        temperature_column=table.temperature_column,
        n_rows=table.n_rows,
        dropped_rows=table.dropped_rows,
        temperature_range_k=value_range(table.temperature_k),
    )


def _check_sweep_count(calibrator, sweeps: tuple, options: dict) -> None:
    """Before any work: several files only for a calibrator that needs the temperature,
    stdin at most once, ``--temperature-k`` once per file."""
    method = options["method"]
    check_temperature_options(
        calibrator,
        f"--method {method}",
        column=options["temperature_column"],
        given=options["temperature_k"],
    )
    if len(sweeps) > 1 and not needs_temperature(calibrator):
        raise InputError(
            f"--method {method} takes one sweep file, got {len(sweeps)}: only a thermal "
            "calibration (--method thermal) is fitted on several sweeps (one per "
            "temperature); merge the files into one if they are one sweep"
        )
    if sum(is_stdio(path) for path in sweeps) > 1:
        raise InputError("only one sweep can be read from stdin ('-')")
    given = options["temperature_k"]
    if given and len(given) != len(sweeps):
        raise InputError(
            f"--temperature-k is given {len(given)} time(s) for {len(sweeps)} sweep file(s); "
            "give it once per file, in file order, or leave it out to read each file's "
            "temperature column"
        )


def _check_same_layout(tables, explicit_ports: bool) -> None:
    """Every sweep file has the first one's ports (names unless --ports) and monitor."""
    first = tables[0]
    names = [port_key(name) for name in first.port_names]
    for table in tables[1:]:
        if len(table.port_names) != len(names) or (
            not explicit_ports and [port_key(name) for name in table.port_names] != names
        ):
            raise InputError(
                f"{table.source} has ports {_port_list(table)} but {first.source} has "
                f"{_port_list(first)}; the sweeps of one calibration need the same ports: "
                "pass --ports with the columns of every file in order"
            )
        if (table.monitor_w is None) != (first.monitor_w is None):
            having, lacking = (table, first) if first.monitor_w is None else (first, table)
            raise InputError(
                f"{having.source} has a power monitor ({having.monitor_column}) and "
                f"{lacking.source} has none; the sweeps of one calibration need a monitor in "
                "every file or in none"
            )


def _read_sweeps(calibrator, sweeps: tuple, request, options: dict) -> _Sweeps:
    """Read every sweep file, check they agree, and find each row's temperature."""
    given = tuple(options["temperature_k"])
    thermal = needs_temperature(calibrator)
    tables = tuple(
        read(
            path,
            request,
            need_x=True,
            drop_invalid=options["drop_invalid"],
            quiet=options["quiet"],
            temperature=None if not thermal else not given,
        ).valid_only()
        for path in sweeps
    )
    _check_same_layout(tables, request.ports is not None)
    temperature = None
    if thermal and given:
        temperature = np.concatenate(
            [np.full(table.n_rows, value) for table, value in zip(tables, given, strict=True)]
        )
    elif thermal:
        for table in tables:
            if table.temperature_k is None:
                raise missing_temperature(
                    f"--method {options['method']}",
                    table.source,
                    "pass --temperature COL, or --temperature-k T once per sweep file, in "
                    "file order",
                )
        temperature = np.concatenate([table.temperature_k for table in tables])
    return _Sweeps(tables, tuple(map(_record, tables)), temperature, given)


def _in_chunks(options: dict) -> bool:
    """Whether the sweep is read in chunks: the learned method, one map (no --per-fsr)."""
    return options["method"] == "learned" and not options["per_fsr"]


def _fit_in_chunks(calibrator, path, request, options: dict):
    """Read the sweep in chunks and fit the learned calibrator on it (bounded memory)."""
    quiet = options["quiet"]
    label = STDIN_LABEL if is_stdio(path) else str(path)
    stream = iter_readings(
        path,
        request,
        chunk_rows=CHUNK_ROWS,
        need_x=True,
        allow_invalid=options["drop_invalid"],
        name=label,
    )
    dark_w = _dark_w(options, request, stream)

    def progress(description, total, unit):
        return progress_bar(printable(description), total, quiet=quiet, unit=unit)

    with about(label), _refused_if(options["strict"]):
        record = fit_sweep_chunks(calibrator, stream, dark_w=dark_w, progress=progress)
    if record.dropped_rows:
        note(
            quiet,
            f"{record.source}: skipped {record.dropped_rows} invalid row(s), first: "
            f"{', '.join(record.invalid_examples[:3])}",
        )
    return calibrator, _Sweeps((), (record,), None, ())


def _check_stage_groups(stage_ports, fsrs_hz) -> None:
    """Before any work: ``--stage-ports`` gives one group of 3 or more columns per FSR."""
    if len(stage_ports) != len(fsrs_hz):
        raise InputError(
            f"--stage-ports gives the columns of {len(stage_ports)} stage(s) but --fsr has "
            f"{len(fsrs_hz)} ({_fsr_list_text(fsrs_hz)}): give one group of columns per FSR, "
            "separated by '/', in the order of the FSRs"
        )
    small = [index + 1 for index, stage in enumerate(stage_ports) if len(stage) < 3]
    if small:
        raise InputError(
            f"--stage-ports gives stage(s) {', '.join(map(str, small))} fewer than 3 columns; "
            "every stage needs 3 or more ports"
        )


def _stage_columns(stage_ports, table) -> tuple:
    """``--stage-ports`` (positions from 1) as the cascade's columns (from 0), checked
    against the sweep's port columns: every one in a stage, none beyond them."""
    ports = len(table.port_names)
    where = f"{table.source} has {ports} port columns ({_port_list(table)})"
    given = {position for stage in stage_ports for position in stage}
    beyond = sorted(given - set(range(1, ports + 1)))
    if beyond:
        raise InputError(
            f"--stage-ports names column(s) {', '.join(map(str, beyond))} but {where}; give "
            "positions from 1 to the number of port columns (choose the columns with --ports)"
        )
    missing = sorted(set(range(1, ports + 1)) - given)
    if missing:
        names = ", ".join(table.port_names[position - 1] for position in missing)
        raise InputError(
            f"--stage-ports gives no stage column(s) {', '.join(map(str, missing))} ({names}), "
            f"but {where}: give every port column to a stage, or read only the stages' columns "
            "with --ports"
        )
    return tuple(tuple(position - 1 for position in stage) for stage in stage_ports)


def _fit(options: dict, calibrator, paths: tuple, request):
    """Read the sweeps and fit the calibrator: in chunks for the learned method, whole for
    the others; the fitted calibrator and what was read."""
    if _in_chunks(options):
        return _fit_in_chunks(calibrator, paths[0], request, options)
    sweeps = _read_sweeps(calibrator, paths, request, options)
    if options["stage_ports"] is not None:
        calibrator.set_params(stage_ports=_stage_columns(options["stage_ports"], sweeps.first))
    dark_w = _dark_w(options, request, sweeps.first)
    extra = {} if sweeps.temperature_k is None else {"temperature_k": sweeps.temperature_k}
    description = printable(f"calibrating on {sweeps.label}")
    with busy(description, quiet=options["quiet"]), about(sweeps.label):
        with _refused_if(options["strict"]):
            calibrator.fit(
                sweeps.powers_w,
                sweeps.x_hz,
                sweeps.monitor_w,
                list(sweeps.first.port_names),
                dark_w=dark_w,
                **extra,
            )
    return calibrator, sweeps


def _one_or_list(values: list):
    """The value every file shares, or the list of each file's (metadata)."""
    return values[0] if all(value == values[0] for value in values) else values


def _metadata(sweeps: _Sweeps, dark_file) -> dict:
    """What the calibration was read from, kept in the calibration file (the dark readings'
    file only when there was one). One sweep file: its name and columns; several: the list
    of names, and each column entry a list where the files differ."""
    records = sweeps.records
    several = len(records) > 1
    temperature = sweeps.temperature_range_k
    metadata = {
        "sweep_file": [str(t.source) for t in records] if several else str(sweeps.first.source),
        "x_column": _one_or_list([t.x_column for t in records]),
        "x_unit": _one_or_list([t.x_unit for t in records]),
        "port_columns": _one_or_list([list(t.port_names) for t in records]),
        "port_units": _one_or_list([list(t.port_units) for t in records]),
        "monitor_column": _one_or_list([t.monitor_column for t in records]),
        "temperature_column": None
        if sweeps.given_k
        else _one_or_list([t.temperature_column for t in records]),
        "temperature_k_range": temperature,
        "rows": sweeps.n_rows,
        "dropped_rows": sum(t.dropped_rows for t in records),
    }
    if several:
        metadata["rows_per_file"] = [t.n_rows for t in records]
    if sweeps.given_k:
        metadata["temperature_k_given"] = [float(value) for value in sweeps.given_k]
    if dark_file is not None:
        metadata["dark_file"] = STDIN_LABEL if is_stdio(dark_file) else str(dark_file)
    return metadata


def _read_line(sweeps: _Sweeps) -> str:
    """What was read: files, rows, axis, ports, monitor and temperature."""
    first = sweeps.first
    rows = f"{sweeps.n_rows} rows"
    if len(sweeps.records) > 1:
        rows += f" ({' + '.join(str(record.n_rows) for record in sweeps.records)})"
    text = (
        f"calibrated {sweeps.label}: {rows}, axis {first.x_column} ({first.x_unit}), "
        f"ports {_port_list(first)}"
    )
    if first.monitor_column:
        text += f", monitor {first.monitor_column}"
    if sweeps.temperature_k is not None:
        low, high = sweeps.temperature_k.min(), sweeps.temperature_k.max()
        source = (
            "--temperature-k"
            if sweeps.given_k
            else f"column {', '.join(dict.fromkeys(t.temperature_column for t in sweeps.records))}"
        )
        text += f", temperature {low:.6g} to {high:.6g} K ({source})"
    return text


@click.command()
@click.argument(
    "sweeps", metavar="SWEEP [SWEEP ...]", nargs=-1, required=True, type=click.Path(dir_okay=False)
)
@out_option("Calibration file to write: JSON, e.g. chip.wmcal.json ('-' for stdout).")
@setting(
    "--fsr",
    "50GHz",
    FSRS,
    "Design FSR: 50GHz, '49.69 GHz'; a bare number is in Hz (5e10). --method cascade: every "
    "stage's, coarsest first (default 5THz,500GHz,50GHz).",
    metavar="FSR[,FSR..]",
)
@setting(
    "--fsr-tolerance",
    0.2,
    click.FloatRange(0, 1, min_open=True, max_open=True),
    "Relative half width of the FSR search (learned method).",
)
@click.option(
    "--method",
    type=click.Choice(("learned", "conventional", "thermal", "wideband", "cascade")),
    default="learned",
    show_default=True,
    help="Learned linear map (paper), the conventional ideal-map method, the learned map "
    "with the chip temperature's effect on bias phase and delay (sweeps at several "
    "temperatures), one learned model across a band of many FSRs (phase polynomial "
    "and a map smooth in frequency; readings then need a coarse frequency), or a cascade "
    "of stages of decreasing FSR (absolute frequency, no coarse input).",
)
@click.option(
    "--retrieval",
    type=click.Choice(("pinv", "ml")),
    default="pinv",
    show_default=True,
    help="Phase retrieval of the learned, thermal, wideband and cascade methods: pseudo-inverse "
    "(paper) or cone-constrained maximum likelihood (reaches the Cramer-Rao bound also for "
    "ill-conditioned maps).",
)
@click.option(
    "--phase-order",
    type=PHASE_ORDER,
    metavar="P",
    help="Order of the phase polynomial of --method wideband: 1 (linear phase, the paper's), "
    "2 (adds dispersion) or higher. Default: chosen by cross-validation on held-out FSRs.",
)
@click.option(
    "--map-order",
    type=MAP_ORDER,
    metavar="J",
    help="Legendre order of the map's change across the band of --method wideband: 0 (one "
    "map) or higher. Default: chosen by cross-validation on held-out FSRs.",
)
@click.option(
    "--stage-ports",
    type=STAGE_PORTS,
    help="Port columns of each stage of --method cascade, by position among the port "
    "columns read (from 1, in order), stages separated by '/' in the order of --fsr: "
    "1-3/4-6/7-9, 1,3,5/2,4,6/7-9. Default: consecutive blocks of equal size.",
)
@setting(
    "--max-order-error",
    1e-6,
    click.FloatRange(0, 1, min_open=True, max_open=True),
    "Probability of a wrong fringe order above which --method cascade flags a reading "
    "ORDER_AMBIGUOUS, and the wrong-order rate at the sweep's noise above which it refuses "
    "a hand-over between stages.",
    metavar="P",
)
@temperature_k_option(
    "Chip temperature of every reading of a sweep file (thermal method), once per file in "
    "file order: 293.15 (K), 293.15K, 20C. Default: each file's temperature column.",
    multiple=True,
)
@setting(
    "--temperature-std-k",
    DEFAULT_TEMPERATURE_STD_K,
    click.FloatRange(0, min_open=True),
    "Noise of the temperature readings in use (K, thermal method): adds the fitted rate "
    "times it to each reading's frequency uncertainty.",
    metavar="K",
)
@PORT_PHASES
@click.option(
    "--per-fsr",
    is_flag=True,
    help="Calibrate each FSR of a multi-FSR sweep on its own (a calibration set).",
)
@click.option(
    "--dark",
    "dark_file",
    metavar="FILE",
    type=click.Path(dir_okay=False),
    help="Readings with the source off, with the sweep's port columns (any supported format, "
    "no frequency column needed); their mean per port is subtracted from every reading.",
)
@click.option(
    "--dark-w",
    type=OFFSETS,
    metavar="W,W,..",
    help="Dark reading of each port, in port order: 1uW,-20nW,0 (signed; a bare number is "
    "in W); subtracted from every reading.",
)
@click.option(
    "--strict",
    is_flag=True,
    help="Treat calibration warnings as errors: write nothing and exit with code 3.",
)
@column_options()
@FORCE
@QUIET
def calibrate(sweeps, out_path, port_phases_deg, force, **options):
    """Learn a calibration from a sweep of known frequencies.

    SWEEP is a CSV/TSV, HDF5, MAT, NPZ or Parquet file ('-' for stdin) with a frequency
    or wavelength column and three or more port columns. The calibration file must not
    exist unless --force is given; with -o - it goes to stdout and the summary to stderr.
    Calibration warnings print as 'warning: [cause] ...' lines on stderr (also with
    --quiet); with --strict they are errors (exit code 3) and nothing is written.

    --method thermal takes one or more sweeps (at two or more temperatures, or one
    recording while the temperature changes), concatenated in the order given, with the
    chip temperature of every reading from a temperature column (found by name with its
    unit, e.g. temperature_K or 'Temp (C)', or --temperature COL) or --temperature-k once
    per file. The other methods take one sweep.

    --method wideband fits one model across a sweep of many FSRs (whole FSRs may be
    missing): a phase polynomial of order --phase-order and a map of Legendre order
    --map-order in frequency, both chosen by cross-validation on held-out FSRs unless
    given. Measuring with it needs a coarse frequency of each reading within half an
    FSR (--coarse or --coarse-frequency), which picks the fringe order.

    --method cascade calibrates stages of decreasing FSR (--fsr 5THz,500GHz,50GHz,
    coarsest first; the coarsest must exceed the band) from one sweep over the band: the
    port columns read, in order, are the stages' columns, in consecutive blocks of equal
    size or as --stage-ports says. Each stage picks the fringe order of the next, so
    readings need no coarse frequency; a hand-over the sweep's noise makes unreliable
    (wrong-order rate above --max-order-error) is refused with the largest FSR ratio the
    noise allows.

    The learned method (the default, without --per-fsr) reads the sweep in chunks, with a
    progress bar, in memory bounded by the chunk: files larger than memory work. Beyond
    2^17 readings it is fitted on sums over every reading and its checks and diagnostics
    see every k-th reading (the summary says how many). The other methods and --per-fsr
    read the whole sweep into memory.

    \b
    Example:
      wavemeter calibrate sweep.csv -o chip.wmcal.json --fsr 50GHz
      wavemeter calibrate sweep.csv -o chip.wmcal.json --dark dark.csv --strict
      wavemeter calibrate lab.csv -o chip.wmcal.json --fsr '49.69 GHz' \\
          --x 'Wavelength (nm)' --ports 'Port 1 [dBm]','Port 2 [dBm]','Port 3 [dBm]'
      wavemeter calibrate --method thermal cold.csv mid.csv warm.csv -o chip.wmcal.json
      wavemeter calibrate --method thermal a.csv b.csv --temperature-k 20C \\
          --temperature-k 21.5C -o chip.wmcal.json
      wavemeter calibrate --method wideband band.csv -o band.wmcal.json
      wavemeter calibrate --method wideband band.csv -o band.wmcal.json --phase-order 2
      wavemeter calibrate --method cascade cband.csv -o cascade.wmcal.json \\
          --fsr 5THz,500GHz,50GHz --stage-ports 1-3/4-6/7-9
    """
    from ..calibration.files.document import save_calibration

    dark_file = options["dark_file"]
    if dark_file is not None and options["dark_w"] is not None:
        raise InputError(
            "--dark and --dark-w both give the dark readings; give a file or values, not both"
        )
    if dark_file is not None and is_stdio(dark_file) and any(map(is_stdio, sweeps)):
        raise InputError("the sweep and --dark cannot both be read from stdin ('-')")
    calibrator = _calibrator(options, port_phases_rad(port_phases_deg))
    _check_sweep_count(calibrator, sweeps, options)
    check_calibration_output(out_path, (*sweeps, *([dark_file] if dark_file else [])), force)
    request = column_request(options)
    quiet = options["quiet"]
    calibration, read_sweeps = _fit(options, calibrator, sweeps, request)
    with output_path(out_path) as target:
        save_calibration(calibration, target, _metadata(read_sweeps, dark_file))
    to_stderr = is_stdio(out_path)
    say(quiet, _read_line(read_sweeps), err=to_stderr)
    say(quiet, calibration.summary().text, err=to_stderr)
    say(quiet, f"wrote {'the calibration to stdout' if to_stderr else out_path}", err=to_stderr)


command = calibrate

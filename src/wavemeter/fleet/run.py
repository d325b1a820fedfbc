"""Calibrating a fleet of devices, in parallel on dask.distributed or in this process.

The only module of the package that imports ``distributed``, and only when a fleet runs on
it. One task per device (:func:`wavemeter.jobs.fleet_device.calibrate_device`) runs on a
worker: it reads the device's sweep file (by path: on a cluster, the files must be where
the workers see them) and returns the fitted calibration. The client writes every output:
each device's ``<device>.wmcal.json`` as its result arrives, then ``summary.csv``,
``summary.parquet`` and ``fleet.html``, each atomically (a temporary file renamed into
place). So OUTDIR need only be writable here, a task cancelled on a worker can write
nothing, and no file is ever half-written.

Every device is calibrated by :func:`wavemeter.jobs.calibrate_file`, the job ``wavemeter
calibrate`` runs: its file is the one ``calibrate`` writes of the same sweep with the same
options, apart from ``DIFFERING_FIELDS`` (:mod:`wavemeter.jobs.calibrate`).

Resume: a device whose calibration file exists, loads and was made with the same options
(its metadata's ``calibrate_options``) is not calibrated again; its row is read from the
file (``resumed``). A file that does not load or was made with other options is a failed
row saying so, and is left untouched, unless ``force`` (then every device is calibrated
and its file replaced). The summary files and the page describe the last run and are
always replaced.

Interruption (Ctrl-C, ``KeyboardInterrupt``): the tasks still queued or running are
cancelled, the calibrations already written stay (each complete), no summary is written,
and the interrupt is raised again; a second run resumes. The workers of a local cluster
ignore SIGINT (it is this process's to handle), and so does this process during the few
seconds the cluster starts.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from ..atomic import check_output
from ..exceptions import FileFormatError, InputError, shown
from ..jobs.calibrate import ERROR, DeviceResult
from ..jobs.calibrator import CalibrateOptions, build_calibrator, options_record
from ..jobs.fleet_device import calibrate_device, saved_result
from .page import write_page
from .summary import write_summary

__all__ = [
    "calibrate_fleet",
    "FleetResult",
    "CALIBRATION_SUFFIX",
    "SUMMARY_CSV",
    "SUMMARY_PARQUET",
    "PAGE",
]

#: the name of a device's calibration in OUTDIR is its name with this suffix
CALIBRATION_SUFFIX = ".wmcal.json"
SUMMARY_CSV = "summary.csv"
SUMMARY_PARQUET = "summary.parquet"
PAGE = "fleet.html"
#: what to install for a fleet on dask.distributed
_INSTALL = "pip install 'wavemeter[fleet]'"


@dataclass(frozen=True)
class FleetResult:
    """What :func:`calibrate_fleet` did.

    Attributes
    ----------
    rows : tuple of DeviceResult
        One per device, in the order of the input files.
    out_dir : Path
        The output folder.
    summary_csv, summary_parquet, page : Path
        The summary files and the HTML page written in it.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import wavemeter as wm
    >>> from wavemeter.fleet import calibrate_fleet
    >>> from wavemeter.io import write_table
    >>> folder = Path(tempfile.mkdtemp())
    >>> paths = []
    >>> for seed, name in ((7, "die_x01_y02"), (8, "die_x02_y02")):  # two chips of a wafer
    ...     device = wm.Interferometer.table1(ports=3, seed=seed)
    ...     f_hz = device.sweep_hz(200)
    ...     powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    ...     columns = {"frequency_hz": f_hz, **{f"p{k + 1}_w": powers[:, k] for k in range(3)}}
    ...     write_table(folder / f"{name}.csv", columns)
    ...     paths.append(folder / f"{name}.csv")
    >>> fleet = calibrate_fleet(paths, folder / "out", workers=0, fsr_hz=50e9)  # in-process
    >>> fleet.summary_csv.name, fleet.page.name
    ('summary.csv', 'fleet.html')

    Each row is a device's DeviceResult: both chips read near the Cramer-Rao bound:

    >>> for row in fleet.rows:
    ...     print(row.device, f"FSR {row.fsr_hz / 1e9:.2f} GHz, {row.crlb_ratio:.2f} x the bound")
    die_x01_y02 FSR 51.51 GHz, 1.00 x the bound
    die_x02_y02 FSR 57.03 GHz, 1.06 x the bound
    """

    rows: tuple[DeviceResult, ...]
    out_dir: Path
    summary_csv: Path
    summary_parquet: Path
    page: Path

    @property
    def calibrated(self) -> int:
        """Devices with a calibration (resumed ones included)."""
        return sum(row.ok for row in self.rows)

    @property
    def resumed(self) -> int:
        """Devices whose calibration was found from an earlier run."""
        return sum(row.ok and row.resumed for row in self.rows)

    @property
    def failed(self) -> int:
        """Devices that failed."""
        return len(self.rows) - self.calibrated


def _sources(paths) -> list[Path]:
    """The input files, each device's name (stem) once."""
    if isinstance(paths, (str, os.PathLike)):
        raise InputError(
            f"paths must be a sequence of sweep files, got the single path {str(paths)!r}: "
            "pass a list (expand a folder or a glob pattern first)",
            parameter="paths",
        )
    sources = [Path(path) for path in paths]
    if not sources:
        raise InputError("no sweep files to calibrate: paths is empty", parameter="paths")
    seen: dict[str, Path] = {}
    for path in sources:
        if path.stem in seen:
            raise InputError(
                f"{seen[path.stem]} and {path} are both device {path.stem!r} (a device is named "
                "by its file's stem, and so is its calibration): rename one, or calibrate them "
                "into different folders",
                parameter="paths",
            )
        seen[path.stem] = path
    return sources


def _out_folder(out_dir) -> Path:
    folder = Path(out_dir)
    if not str(out_dir) or str(out_dir) == "-":
        raise InputError("a fleet is written into a folder: give its name", parameter="out_dir")
    if folder.exists() and not folder.is_dir():
        raise InputError(
            f"{folder} is a file: a fleet is written into a folder; give a folder name",
            parameter="out_dir",
        )
    if not folder.parent.is_dir():
        raise InputError(
            f"cannot write to {folder}: folder {folder.parent} does not exist", parameter="out_dir"
        )
    return folder


def _check_workers(client, workers, scheduler) -> None:
    if client is not None and (workers is not None or scheduler is not None):
        raise InputError(
            "a client runs the fleet on its own cluster: give client alone, without workers "
            "or scheduler",
            parameter="client",
        )
    if scheduler is not None and workers is not None:
        raise InputError(
            "workers is the size of a local cluster; a scheduler has its own workers: give "
            "one of workers and scheduler",
            parameter="workers",
        )
    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, int) or workers < 0
    ):
        raise InputError(
            f"workers must be a whole number >= 0 (0: in this process), got {shown(workers)}",
            parameter="workers",
        )


def _flat(record) -> dict:
    """A ``calibrate_options`` record with the calibrator's settings among the others."""
    if not isinstance(record, dict):
        return {}
    settings = record.get("settings")
    rest = {name: value for name, value in record.items() if name != "settings"}
    return {**settings, **rest} if isinstance(settings, dict) else rest


def _resumed(output: Path, source: Path, options: dict) -> DeviceResult:
    """The row of a device whose calibration file exists: resumed, or why not."""
    try:
        result = saved_result(output, source, source.stem)
    except FileFormatError as exc:
        return DeviceResult(
            device=source.stem,
            source=str(source),
            status=ERROR,
            error=f"{exc}; it was left untouched: remove it, or recalibrate every device (force)",
        )
    saved = result.metadata.get("calibrate_options")
    if saved != options:
        saved, options = _flat(saved), _flat(options)
        differ = ", ".join(
            f"{name} {saved.get(name)!r} (now {options.get(name)!r})"
            for name in dict.fromkeys([*options, *saved])
            if saved.get(name) != options.get(name)
        )
        return DeviceResult(
            device=source.stem,
            source=str(source),
            status=ERROR,
            error=f"{output} exists and was made with other options: {differ}; it was left "
            "untouched: calibrate into another folder, or recalibrate every device (force)",
        )
    return result


def _distributed():
    try:
        import distributed
    except ImportError as exc:
        raise InputError(
            f"a fleet on a dask cluster needs dask.distributed: {_INSTALL}; or calibrate in "
            "this process (workers=0)",
            parameter="workers",
        ) from exc
    return distributed


@contextlib.contextmanager
def _interrupts_ignored():
    """SIGINT ignored while the block runs (in the main thread; elsewhere no signal comes).

    Processes started meanwhile inherit it, and Python leaves an ignored SIGINT ignored:
    the workers of a local cluster do not see the terminal's Ctrl-C, which goes to their
    process group too; this process takes it, cancels the tasks and closes the cluster.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _run_serial(tasks, job: dict, done: Callable) -> None:
    for index, path in tasks:
        done(index, calibrate_device(path, **job))


def _run_dask(tasks, job: dict, done: Callable, client, workers, scheduler) -> None:
    """One task per device on ``client``, or on a client of ``scheduler``, or of a new
    LocalCluster of ``workers`` processes (one thread each; None: one per core);
    ``done(index, result)`` as each completes. On any exception, also an interrupt, the
    remaining tasks are cancelled."""
    distributed = _distributed()
    with contextlib.ExitStack() as stack:
        if client is None and scheduler is not None:
            try:
                client = stack.enter_context(distributed.Client(scheduler))
            except (OSError, ValueError) as exc:  # no answer; not an address
                raise InputError(
                    f"cannot connect to the dask scheduler at {scheduler}: {exc}",
                    parameter="scheduler",
                ) from exc
        elif client is None:
            with _interrupts_ignored():  # the workers inherit it: Ctrl-C is the client's
                cluster = stack.enter_context(
                    distributed.LocalCluster(
                        n_workers=workers or os.cpu_count() or 1,
                        threads_per_worker=1,
                        dashboard_address=None,
                        # a worker whose heartbeat meets the closing scheduler logs an
                        # ERROR with a traceback; a device's own failure comes back as
                        # its result, so only a critical log is the user's business
                        silence_logs=logging.CRITICAL,
                    )
                )
            client = stack.enter_context(distributed.Client(cluster))
        futures = {
            client.submit(calibrate_device, path, pure=False, **job): index for index, path in tasks
        }
        try:
            for future in distributed.as_completed(futures):
                done(futures[future], future.result())
        except BaseException:
            client.cancel(list(futures))
            raise


def calibrate_fleet(
    paths: Sequence,
    out_dir,
    *,
    client=None,
    workers: int | None = None,
    scheduler: str | None = None,
    force: bool = False,
    progress: Callable | None = None,
    options: CalibrateOptions | None = None,
    check: Callable | None = None,
    **calibrate_options,
) -> FleetResult:
    """Calibrate every device of a fleet from its sweep file, in parallel.

    Parameters
    ----------
    paths : sequence of str or Path
        The sweep files, one per device; a device is named by its file's stem (names must
        be unique). On a cluster, the workers read them by these paths.
    out_dir : str or Path
        Output folder (created if missing; its parent must exist): ``<device>.wmcal.json``
        per device, ``summary.csv``, ``summary.parquet``, ``fleet.html``.
    client : distributed.Client, optional
        Run on this client's cluster.
    workers : int, optional
        0: calibrate in this process, one device after the other (dask is not imported).
        Otherwise the number of worker processes of a new ``distributed.LocalCluster``
        (one thread each; None: one per core), closed at the end.
    scheduler : str, optional
        Address of a running dask scheduler (``tcp://host:8786``) to run on instead.
    force : bool
        Calibrate every device and replace its calibration file; without it a device whose
        calibration exists is resumed (see the module's text).
    progress : callable, optional
        ``progress(description, total, unit=...)`` returning a context manager that yields
        ``advance(steps)`` (as :func:`wavemeter.progress.progress_bar`); advanced by one
        for every device calibrated. None: silent.
    options : CalibrateOptions, optional
        What to calibrate every device with (:func:`wavemeter.jobs.calibrate_file`); or
    **calibrate_options
        its fields and the method's settings as keywords: ``method``, ``fsr_hz``,
        ``fsr_tolerance``, ``retrieval``, ``request``, ``drop_invalid``, ``phase_order``...
    check : callable, optional
        ``check(layout)`` of each device's sweep, as :func:`wavemeter.jobs.calibrate_file`
        takes it (run on the workers: what it raises fails the device).

    Returns
    -------
    FleetResult
        The rows in the order of ``paths``.

    Raises
    ------
    InputError
        Before any work: no files, two files with one stem, an output folder that is a
        file or whose parent is missing, an unknown method or setting, both a client and
        workers or a scheduler, dask or pyarrow missing, a scheduler that does not answer.
        A device that fails is a row with ``status="error"``, not an error.
    KeyboardInterrupt
        Raised again after cancelling the remaining tasks; no summary is written.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import wavemeter as wm
    >>> from wavemeter.fleet import calibrate_fleet
    >>> from wavemeter.io import write_table
    >>> folder = Path(tempfile.mkdtemp())
    >>> paths = []
    >>> for seed, name in ((7, "die_x01_y02"), (8, "die_x02_y02")):  # two chips of a wafer
    ...     device = wm.Interferometer.table1(ports=3, seed=seed)
    ...     f_hz = device.sweep_hz(200)
    ...     powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    ...     columns = {"frequency_hz": f_hz, **{f"p{k + 1}_w": powers[:, k] for k in range(3)}}
    ...     write_table(folder / f"{name}.csv", columns)
    ...     paths.append(folder / f"{name}.csv")
    >>> fleet = calibrate_fleet(paths, folder / "out", workers=0, fsr_hz=50e9)  # in-process
    >>> [(row.device, row.status) for row in fleet.rows]
    [('die_x01_y02', 'ok'), ('die_x02_y02', 'ok')]
    >>> for path in sorted(fleet.out_dir.iterdir()):  # a calibration per device, the summaries
    ...     print(path.name)
    die_x01_y02.wmcal.json
    die_x02_y02.wmcal.json
    fleet.html
    summary.csv
    summary.parquet
    """
    from ..io.parquet import require_pyarrow

    _check_workers(client, workers, scheduler)
    sources = _sources(paths)
    folder = _out_folder(out_dir)
    if options is None:
        options = CalibrateOptions.from_keywords(**calibrate_options)
    elif calibrate_options:
        raise InputError(
            f"give the options or keywords, not both (got {', '.join(calibrate_options)})",
            parameter="options",
        )
    record = options_record(options, build_calibrator(options))
    require_pyarrow("writing")
    outputs = [folder / f"{path.stem}{CALIBRATION_SUFFIX}" for path in sources]
    summary = [folder / name for name in (SUMMARY_CSV, SUMMARY_PARQUET, PAGE)]
    if folder.is_dir():  # a new folder holds no input
        for output in [*outputs, *summary]:
            check_output(output, inputs=sources, force=True)
    folder.mkdir(exist_ok=True)
    rows: list[DeviceResult | None] = [None] * len(sources)
    tasks = []
    for index, (source, output) in enumerate(zip(sources, outputs, strict=True)):
        if not force and os.path.lexists(output):
            rows[index] = _resumed(output, source, record)
        else:
            tasks.append((index, source))
    with contextlib.ExitStack() as stack:
        advance = None
        if progress is not None and tasks:
            advance = stack.enter_context(
                progress(f"calibrating {len(tasks)} devices", len(tasks), unit="devices")
            )

        def done(index: int, result: DeviceResult) -> None:
            if result.ok:
                from ..calibration import save_calibration

                save_calibration(result.calibration, outputs[index], result.metadata)
            rows[index] = result
            if advance is not None:
                advance(1)

        job = {"options": options, "check": check}
        if tasks and client is None and workers == 0:
            _run_serial(tasks, job, done)
        elif tasks:
            _run_dask(tasks, job, done, client, workers, scheduler)
    rows = tuple(rows)
    write_summary(rows, summary[0], summary[1])
    write_page(rows, summary[2])
    return FleetResult(rows, folder, *summary)

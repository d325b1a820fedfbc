"""`wavemeter fleet calibrate`: calibrate every device of a fleet, in parallel.

Each sweep file is one device, named by the file's stem. The devices are calibrated on a
``distributed.LocalCluster`` of ``--workers`` processes (default: one per core), on a
running dask scheduler with ``--scheduler ADDRESS``, or in this process with
``--workers 0`` (:func:`wavemeter.fleet.calibrate_fleet`). OUTDIR gets
``<device>.wmcal.json`` per device, ``summary.csv`` and ``summary.parquet`` (one row per
device) and ``fleet.html``.

Every device is calibrated by the job ``wavemeter calibrate`` runs
(:func:`wavemeter.jobs.calibrate_file`), with the same method options: its calibration file
is the one ``calibrate`` writes of the same sweep with the same options, but for the fields
:data:`wavemeter.jobs.calibrate.DIFFERING_FIELDS` names (the time it was written, the sweep
file as named).

A device that fails is a row of the summary with its error; the others go on. When the
run completes and some devices failed, one ``warning:`` line says how many (exit code 0);
when none calibrated, an ``error:`` line (exit code 2). A second run skips the devices already
calibrated with the same options (resume); ``--force`` recalibrates every one. Ctrl-C
stops the run (exit code 130): the calibrations written stay, each complete, and no
summary is written.
"""

from __future__ import annotations

from collections import Counter

import click

from ..exceptions import InputError
from ..fleet import calibrate_fleet
from ..progress import progress_bar
from ._common import QUIET, column_options, column_request, one_line, printable, say
from ._data_files import data_files, names_many_files
from ._methods import calibrate_options, method_options


def _sweep_files(sweeps) -> list:
    """Every sweep file the arguments name: files as given, a folder's data files, the
    files a quoted glob pattern matches; in argument order, each pattern's in name order."""
    files = []
    for sweep in sweeps:
        files += data_files(sweep) if names_many_files(sweep) else [sweep]
    return files


def _workers(workers, scheduler):
    """The library's ``workers``: None (a cluster's own, or one per core) unless given."""
    if scheduler is not None and workers is not None:
        raise InputError(
            "--workers sets the size of a local cluster; --scheduler runs on a cluster's own "
            "workers: give one of them"
        )
    return workers


@click.group()
def fleet():
    """Work on many devices at once (a wafer of chips), in parallel on dask.

    \b
    Example:
      wavemeter fleet calibrate wafer7/ -o wafer7-cal
    """


@fleet.command()
@click.argument("sweeps", metavar="DIR_OR_GLOB [...]", nargs=-1, required=True)
@click.option(
    "-o",
    "--out",
    "out_dir",
    required=True,
    type=click.Path(file_okay=False),
    help="Output folder (created if missing): <device>.wmcal.json, summary.csv, "
    "summary.parquet, fleet.html.",
)
@method_options
@click.option(
    "--scheduler",
    metavar="ADDRESS",
    help="Run on this running dask scheduler (tcp://host:8786) instead of a local cluster; "
    "its workers must see the sweep files by the same paths.",
)
@click.option(
    "--workers",
    type=click.IntRange(0),
    help="Worker processes of the local cluster (default: one per core); 0: calibrate in "
    "this process, one device after the other, without dask.",
)
@column_options()
@click.option("--force", is_flag=True, help="Recalibrate every device and replace its calibration.")
@QUIET
def calibrate(sweeps, out_dir, scheduler, workers, force, **options):
    """Calibrate every device (one sweep file each) into OUTDIR, in parallel.

    DIR_OR_GLOB is a folder (its data files), a quoted glob pattern ('wafer/*.csv') or a
    file; several may be given. Every device is named by its file's stem (die_x03_y12.csv
    is device die_x03_y12; names must be unique); x/y in the name place it on the wafer
    map. The devices share the method, its settings and the column options, as calibrate
    takes them (a thermal device's temperature from its file's temperature column); each
    device's calibration file is the one calibrate writes of its sweep with the same
    options, but for the time it was written and the sweep file as named.

    \b
    Example:
      wavemeter fleet calibrate wafer7/ -o wafer7-cal
      wavemeter fleet calibrate 'runs/*.csv' -o cal --fsr 49.7GHz --workers 8
      wavemeter fleet calibrate wafer7/ -o wafer7-cal --scheduler tcp://10.0.0.5:8786
    """
    quiet = options["quiet"]
    job, check = calibrate_options(
        options, request=column_request(options), drop_invalid=options["drop_invalid"]
    )
    files = _sweep_files(sweeps)

    def progress(description, total, unit):
        return progress_bar(printable(description), total, quiet=quiet, unit=unit)

    result = calibrate_fleet(
        files,
        out_dir,
        workers=_workers(workers, scheduler),
        scheduler=scheduler,
        force=force,
        progress=progress,
        options=job,
        check=check,
    )
    total = len(result.rows)
    failed = f"{result.failed} failed"
    if result.resumed:
        fresh = result.calibrated - result.resumed
        say(
            quiet,
            f"{result.calibrated} of {total} devices have a calibration in {result.out_dir}: "
            f"{fresh} calibrated now, {result.resumed} kept from an earlier run, {failed}",
        )
    else:
        say(
            quiet,
            f"calibrated {result.calibrated} of {total} devices into {result.out_dir} ({failed})",
        )
    causes = Counter(cause for row in result.rows for cause in row.warnings)
    if causes:
        listed = ", ".join(f"{cause} ({count})" for cause, count in causes.most_common())
        say(quiet, f"calibration warnings by cause (devices): {listed}")
    say(quiet, f"wrote {result.summary_csv}, {result.summary_parquet} and {result.page}")
    failed = [row for row in result.rows if not row.ok]
    if not failed:
        return
    first = failed[0]
    text = (
        f"{len(failed)} of {total} devices failed (first: {first.device}: {first.error}); "
        f"see {result.summary_csv}"
    )
    if result.calibrated == 0:
        raise InputError(f"no device calibrated: {text}")
    click.echo(one_line("warning: ", text), err=True)


command = fleet

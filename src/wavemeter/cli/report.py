"""`wavemeter report`: an HTML report of a calibration on its sweep.

A calibration that needs the chip temperature (a thermal one) reads it from the sweep's
and the test file's temperature columns; its report adds the error against temperature.
"""

from __future__ import annotations

import click

from ..progress import busy
from ._common import (
    FORCE,
    PORT_PHASES,
    QUIET,
    check_ports,
    column_options,
    column_request,
    load,
    out_option,
    port_phases_rad,
    read,
    say,
)
from ._temperature import missing_temperature, needs_temperature


@click.command()
@click.argument("calibration_file", metavar="CAL", type=click.Path(dir_okay=False))
@click.argument("sweep", type=click.Path(dir_okay=False))
@click.argument("test", required=False, type=click.Path(dir_okay=False))
@out_option("HTML report to write; figures go beside it as <name>-<figure>.png files.")
@FORCE
@PORT_PHASES
@column_options()
@QUIET
def report(calibration_file, sweep, test, out_path, force, port_phases_deg, **options):
    """Write an HTML report with figures of a calibration on its sweep (and a test file).

    The page names its input files and shows the fit (fringes and residuals, every window
    of a per-FSR set), the errors of both methods against the Cramer-Rao bound, and the
    paper's figures. Existing outputs (the page or its PNGs) are replaced only with
    --force.

    A thermal calibration is compared with the plain learned calibration fitted on the
    same sweep, and the page adds its thermal rates and the frequency error against the
    chip temperature: SWEEP and TEST need a temperature column (found by name with its
    unit, or --temperature COL). Give a TEST file recorded at several temperatures to see
    the error over them.

    \b
    Example:
      wavemeter report chip.wmcal.json sweep.csv sweep-test.csv -o report.html
      wavemeter report thermal.wmcal.json s293.5.csv ramp-test.csv -o thermal-report.html
    """
    from ..report.html import write_report

    calibration = load(calibration_file)
    request = column_request(options)
    tables = []
    for path in (sweep, test):
        if path is None:
            tables.append(None)
            continue
        table = read(
            path, request, need_x=True, drop_invalid=options["drop_invalid"], quiet=options["quiet"]
        ).valid_only()
        check_ports(calibration, calibration_file, table, request.ports is not None)
        if needs_temperature(calibration) and table.temperature_k is None:
            raise missing_temperature(
                f"{calibration_file} is a {calibration.method_label} calibration: its report",
                table.source,
                "add a temperature column with its unit (temperature_K, 'Temp (C)') or "
                "name it with --temperature COL",
            )
        tables.append(table)
    with busy(f"writing {out_path}", quiet=options["quiet"]):
        written = write_report(
            calibration,
            tables[0],
            tables[1],
            out_html=out_path,
            port_phases_rad=port_phases_rad(port_phases_deg),
            force=force,
            input_files={"calibration": calibration_file, "sweep": sweep, "test": test},
        )
    say(options["quiet"], f"wrote {', '.join(str(path) for path in written)}")


command = report

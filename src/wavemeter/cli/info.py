"""`wavemeter info`: what a calibration file holds."""

from __future__ import annotations

import json
from pathlib import Path

import click

from ._common import (
    load,
    summary_lines,
)


@click.command()
@click.argument("calibration_file", metavar="CAL", type=click.Path(dir_okay=False))
def info(calibration_file):
    """Print a summary of a calibration file.

    \b
    Example:
      wavemeter info chip.wmcal.json
    """
    calibration = load(calibration_file)
    document = json.loads(Path(calibration_file).read_text(encoding="utf-8"))
    click.echo(
        f"{calibration_file}: wavemeter {document.get('wavemeter_version')} calibration, "
        f"created {document.get('created_utc')}"
    )
    click.echo("\n".join(summary_lines(calibration)))
    source = document.get("metadata") or {}
    if source.get("sweep_file"):
        units = ", ".join(sorted({unit or "relative" for unit in source.get("port_units", [])}))
        click.echo(
            f"sweep            {source['sweep_file']} ({source.get('rows')} rows, axis "
            f"{source.get('x_column')} in {source.get('x_unit')}, ports in {units})"
        )


command = info

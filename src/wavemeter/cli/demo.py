"""`wavemeter demo`: simulate, calibrate, measure and compare on the default device."""

from __future__ import annotations

import click

from ..report.demo import run_demo
from ._common import (
    QUIET,
)


@click.command()
@click.option(
    "--out",
    "out_dir",
    default="wavemeter-demo",
    show_default=True,
    type=click.Path(file_okay=False),
    help="Folder for the sweep, calibration and results files.",
)
@click.option("--seed", default=1, show_default=True, help="Seed of the simulated device.")
@QUIET
def demo(out_dir, seed, quiet):
    """Simulate a Table 1 3x3 device, calibrate it, measure, compare with the CRLB.

    \b
    Example:
      wavemeter demo --out ./wavemeter-demo
    """
    run_demo(out_dir, seed=seed, quiet=quiet)


command = demo

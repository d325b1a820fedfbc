"""`wavemeter demo`: simulate, calibrate, measure and compare on the default device."""

from __future__ import annotations

import click

from ..progress import busy
from ..report.demo import DEMO_FILES, print_demo_summary, run_demo
from ._common import QUIET, say


@click.command()
@click.option(
    "--out",
    "out_dir",
    default="wavemeter-demo",
    show_default=True,
    type=click.Path(file_okay=False),
    help=f"Folder for the demo's files ({', '.join(DEMO_FILES)}); created if missing. "
    "A new run replaces these files and touches nothing else in the folder.",
)
@click.option("--seed", default=1, show_default=True, help="Seed of the simulated device.")
@QUIET
def demo(out_dir, seed, quiet):
    """Simulate a Table 1 3x3 device, calibrate it, measure, compare with the CRLB.

    Run it again and again: it replaces only the files it writes itself in its --out
    folder, and refuses when one of those names is not a regular file there.

    \b
    Example:
      wavemeter demo --out ./wavemeter-demo
    """
    with busy("running the demo", quiet=quiet):
        summary = run_demo(out_dir, seed=seed)
    if not quiet:
        print_demo_summary(summary)
    say(quiet, f"wrote {', '.join(DEMO_FILES)} to {out_dir}/")


command = demo

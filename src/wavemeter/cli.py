"""Command-line interface: ``wavemeter COMMAND ...``.

User errors (bad files, values, options) print one line ``error: ...`` on stderr and exit
with code 2; no traceback, no partial output file.
"""

from __future__ import annotations

import sys

import click

from . import __version__
from .demo import run_demo

__all__ = ["main", "cli"]

USER_ERRORS = (ValueError, TypeError, OSError)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="wavemeter")
def cli():
    """Calibrate multi-port interferometric wavelength meters and retrieve frequency.

    \b
    Example:
      wavemeter demo --out ./wavemeter-demo
    """


@cli.command()
@click.option(
    "--out",
    "out_dir",
    default="wavemeter-demo",
    show_default=True,
    type=click.Path(file_okay=False),
    help="Folder for the sweep, calibration and results files.",
)
@click.option("--seed", default=1, show_default=True, help="Seed of the simulated device.")
@click.option("--quiet", is_flag=True, help="Print nothing but errors.")
def demo(out_dir, seed, quiet):
    """Simulate a Table 1 3x3 device, calibrate it, measure, compare with the CRLB.

    \b
    Example:
      wavemeter demo --out ./wavemeter-demo
    """
    run_demo(out_dir, seed=seed, quiet=quiet)


def main(argv=None) -> int:
    """Run the command line; return the exit code (0 ok, 2 user error)."""
    try:
        cli.main(args=argv, prog_name="wavemeter", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.exceptions.Abort:
        click.echo("error: aborted", err=True)
        return 2
    except click.ClickException as exc:
        click.echo(f"error: {exc.format_message()}", err=True)
        return 2
    except USER_ERRORS as exc:
        message = " ".join(str(exc).split()) or type(exc).__name__
        click.echo(f"error: {message}", err=True)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The ``wavemeter`` group: commands are imported only when they run.

``wavemeter --help`` lists the commands from the table below without importing them, so it
costs little more than importing click. Errors: :class:`wavemeter.WavemeterError` and
``OSError`` become one ``error:`` line and exit code 2; anything else is a bug and shows its
traceback.
"""

from __future__ import annotations

import importlib
import sys

import click

from .._version import __version__
from ..exceptions import WavemeterError

__all__ = ["main", "cli", "COMMANDS"]

#: command -> one-line help shown by ``wavemeter --help``; the module is ``wavemeter.cli.<name>``
COMMANDS = {
    "demo": "Simulate a Table 1 3x3 device, calibrate it, measure, compare with the CRLB.",
    "simulate": "Simulate a sweep of a Table 1 device and write it to a file.",
    "calibrate": "Learn a calibration from a sweep of known frequencies.",
    "measure": "Turn port readings into frequency with a calibration.",
    "evaluate": "Frequency errors on a test file with known frequencies, against the CRLB.",
    "report": "Write an HTML report with figures of a calibration on its sweep.",
    "info": "Print a summary of a calibration file.",
}


class LazyGroup(click.Group):
    """A group whose commands live in their own modules, imported on first use."""

    def list_commands(self, ctx):
        return list(COMMANDS)

    def get_command(self, ctx, cmd_name):
        if cmd_name not in COMMANDS:
            return None
        return importlib.import_module(f"{__package__}.{cmd_name}").command

    def format_commands(self, ctx, formatter):
        with formatter.section("Commands"):
            formatter.write_dl(list(COMMANDS.items()))


@click.group(
    cls=LazyGroup,
    context_settings={"help_option_names": ["-h", "--help"]},
    invoke_without_command=True,
)
@click.version_option(__version__, prog_name="wavemeter")
@click.pass_context
def cli(ctx):
    """Calibrate multi-port interferometric wavelength meters and retrieve frequency.

    \b
    Example:
      wavemeter simulate -o sweep.csv --test 20000
      wavemeter calibrate sweep.csv -o chip.wmcal.json --fsr 50GHz
      wavemeter measure chip.wmcal.json readings.csv -o frequencies.csv
      wavemeter evaluate chip.wmcal.json sweep-test.csv --sweep sweep.csv
    """
    if ctx.invoked_subcommand is None:
        click.echo(ctx.get_help())


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
    except (WavemeterError, OSError) as exc:
        message = " ".join(str(exc).split()) or type(exc).__name__
        click.echo(f"error: {message}", err=True)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())

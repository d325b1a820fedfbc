"""The command group's hint after a library error (``wavemeter.cli.app._option_hint``): the
options of the running command that set the parameter at fault, none where the command has
no such option or none ran.

This tests the module's private function, hence the file named after the module; the hints
as printed by commands are tested in ``test_cli_conventions.py``.
"""

from __future__ import annotations

from wavemeter.cli.app import _option_hint
from wavemeter.exceptions import InputError


def test_hints_follow_the_running_command():
    exists = InputError("x.csv exists", parameter="force")
    assert _option_hint(exists, str(exists), "measure") == " (use --force)"
    assert _option_hint(exists, str(exists), "info") == ""  # info has no --force
    assert _option_hint(exists, str(exists), None) == ""  # no command ran

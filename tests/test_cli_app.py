"""The command group's hint after a library error (``wavemeter.cli.app._with_options``): the
message with the parameter at fault named as the running command's option, unchanged where
the command has no such option or none ran.

This tests the module's private function, hence the file named after the module; the hints
as printed by commands are tested in ``test_cli_conventions.py``.
"""

from __future__ import annotations

from wavemeter.cli.app import _with_options
from wavemeter.exceptions import InputError


def test_hints_follow_the_running_command():
    exists = InputError("x.csv exists", parameter="force")
    assert _with_options(exists, str(exists), "measure") == "x.csv exists (use --force)"
    assert _with_options(exists, str(exists), "info") == "x.csv exists"  # info has no --force
    assert _with_options(exists, str(exists), None) == "x.csv exists"  # no command ran
    few = InputError("found 2 port columns; name them (ports)", parameter="ports")
    assert _with_options(few, str(few), "measure") == "found 2 port columns; name them (--ports)"

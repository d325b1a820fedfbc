"""The command line's shared text helpers (``wavemeter.cli._common``): nothing from a file
reaches the terminal as a control sequence, and OS errors read without Python internals.

These test the module's private names, hence the file named after the module; the
command-line behaviour they serve is tested through ``wavemeter`` commands in
``test_cli_conventions.py`` and ``test_calibration_files.py``.
"""

from __future__ import annotations

from wavemeter.cli._common import error_text, printable


def test_printable_marks_control_characters_but_keeps_tab_and_newline():
    assert printable("a\x1b[31mb\x07\tc\nd\x9b2Je\x7f\x00") == "a?[31mb?\tc\nd?2Je??"
    assert printable("file\u202egnp.exe\u200b") == "file?gnp.exe?"  # bidi override, zero width
    assert printable("Wavelength (µm), P1 [dBm]") == "Wavelength (µm), P1 [dBm]"


def test_printable_replaces_control_characters():
    assert printable("p1\x1b[31m\x07red\u202e\x00") == "p1?[31m?red??"
    assert printable("two\nlines\tand tab") == "two\nlines\tand tab"


def test_os_errors_without_python_internals():
    assert error_text(FileNotFoundError(2, "No such file or directory", "x.csv")) == (
        "x.csv: No such file or directory"
    )
    renamed = OSError(16, "Device or resource busy", "/d/.x.tmp", None, "/d/x")
    assert error_text(renamed) == "/d/x: Device or resource busy"

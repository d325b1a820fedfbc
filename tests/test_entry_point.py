"""``python -m wavemeter`` (``wavemeter/__main__.py``) in this process: the command line's
exit codes and its one ``error:`` line for a usage error, pointing at the help."""

from __future__ import annotations

import runpy
import sys

import pytest

import wavemeter as wm


def _run_module(monkeypatch, capsys, *args) -> tuple[int, str, str]:
    monkeypatch.setattr(sys, "argv", ["wavemeter", *args])
    with pytest.raises(SystemExit) as ended:
        runpy.run_module("wavemeter", run_name="__main__", alter_sys=False)
    out, err = capsys.readouterr()
    return ended.value.code, out, err


def test_version(monkeypatch, capsys):
    code, out, err = _run_module(monkeypatch, capsys, "--version")
    assert (code, err) == (0, "") and out.strip().endswith(f"version {wm.__version__}")


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--nope"], "error: No such option '--nope' (see 'wavemeter --help')"),
        (["measur"], "error: No such command 'measur' (see 'wavemeter --help')"),
        (["measure"], "error: Missing argument 'CAL' (see 'wavemeter measure --help')"),
    ],
)
def test_a_usage_error_is_one_line_pointing_at_the_help(monkeypatch, capsys, args, expected):
    code, out, err = _run_module(monkeypatch, capsys, *args)
    assert (code, out, err) == (2, "", expected + "\n")

"""Every example of ``wavemeter --help`` and of each command's ``--help`` runs as written.

The examples are read from click's rendered help (the lines under ``Example:``, a line
ending in ``\\`` continued on the next), for the commands in the order ``wavemeter --help``
lists them (a group's subcommands after its own), and run in that order in one folder
with the venv's ``wavemeter`` first on PATH, each on the files the examples before it made.
Each must exit 0. The examples that run until stopped (``NEVER_ENDING``) are started,
must show they are up, and are stopped with SIGTERM; the examples that start a service
in the background for later ones (``BACKGROUND``) must leave it running, and it is
stopped at the end. Both lists are checked to be exactly the examples that behave so:
nothing is skipped. The services bind the commands' default ports (serve 5560, 5561,
8560, 5570; dask 8786): a lock file keeps two runs of this test on one machine apart.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from wavemeter.cli.app import cli

#: examples that run until stopped -> what shows they are up: ("text", s) printed on
#: stdout or stderr, or ("file", name) written to by the example's redirection
NEVER_ENDING = {
    "wavemeter stream chip.wmcal.json --follow line.csv > line-f.csv": ("file", "line-f.csv"),
    "wavemeter serve --simulate --channels 3": ("text", "serving simulated"),
    "cat sweep-test.csv | wavemeter serve chip.wmcal.json --log logs/": ("text", "serving "),
    "wavemeter serve chip.wmcal.json --source tcp://127.0.0.1:5570 --channels 4": (
        "text",
        "source tcp://127.0.0.1:5570",
    ),
    "wavemeter serve chip.wmcal.json --source line.csv --follow": ("text", "serving "),
    "wavemeter serve --simulate --channels 2 --reference 1=193.414THz --chip-ramp 2K/60s": (
        "text",
        "serving simulated",
    ),
}
#: examples that start a service in the background, used by the examples after them
BACKGROUND = {
    "dask scheduler --host 127.0.0.1 --dashboard-address 127.0.0.1:0 &",
    "dask worker 127.0.0.1:8786 --host 127.0.0.1 --dashboard-address 127.0.0.1:0 &",
}
#: seconds an example may take to end, or to show it is up
ENDS_WITHIN_S = 600
UP_WITHIN_S = 120
#: seconds the processes of an example's session may take to go once it ended
LEAVES_WITHIN_S = 30
#: exit codes of an example stopped with SIGTERM: the command's clean stop (serve: 0), a
#: command ended like Ctrl-C (128 + SIGTERM), or the shell killed by the signal
STOPPED = {0, 128 + signal.SIGTERM, -signal.SIGTERM}


def help_texts() -> list[tuple[str, str]]:
    """``(command, rendered --help)`` of ``wavemeter`` and every command and subcommand, in
    the order ``wavemeter --help`` lists them."""
    runner = CliRunner()
    texts = []

    def visit(path: list[str], command: click.Command) -> None:
        result = runner.invoke(cli, [*path, "--help"], prog_name="wavemeter")
        assert result.exit_code == 0, result.output
        texts.append((" ".join(["wavemeter", *path]), result.output))
        if isinstance(command, click.Group):
            context = click.Context(command, info_name=path[-1] if path else "wavemeter")
            for name in command.list_commands(context):
                visit([*path, name], command.get_command(context, name))

    visit([], cli)
    return texts


def examples(text: str) -> list[str]:
    """The shell commands under ``Example:`` in one help text, continuations joined."""
    lines = text.splitlines()
    found = []
    for start, line in enumerate(lines):
        if line.strip() != "Example:":
            continue
        indent = len(line) - len(line.lstrip())
        command = ""
        for body in lines[start + 1 :]:
            if not body.strip() or len(body) - len(body.lstrip()) <= indent:
                break
            command += body.strip()
            if command.endswith("\\"):
                command = command[:-1].rstrip() + " "
                continue
            found.append(command)
            command = ""
        assert not command, f"an example ends in a continuation: {command!r}"
    return found


def all_examples() -> list[tuple[str, str]]:
    return [(where, example) for where, text in help_texts() for example in examples(text)]


def test_examples_are_read_from_every_help():
    """The reader finds the examples: every command's help has some, and both lists name
    examples that exist (a renamed example is not skipped unnoticed)."""
    found = all_examples()
    commands = {where for where, _ in found}
    listed = {where for where, _ in help_texts()}
    assert commands == listed, f"help without an example: {sorted(listed - commands)}"
    texts = {example for _, example in found}
    assert set(NEVER_ENDING) <= texts, sorted(set(NEVER_ENDING) - texts)
    assert BACKGROUND <= texts, sorted(BACKGROUND - texts)
    assert all("\\" not in example for example in texts)


class Runner:
    """Runs examples in ``folder``, each in a session of its own, and stops what is left."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}"}
        self.env["PATH"] += os.environ.get("PATH", "")
        self.env.pop("DISPLAY", None)  # serve --simulate opens no browser
        self.sessions: list[subprocess.Popen] = []
        self.outputs: dict[str, str] = {}
        self.count = 0

    def start(self, example: str) -> tuple[subprocess.Popen, Path, Path]:
        self.count += 1
        out = self.folder.parent / f"example-{self.count:02d}.out"
        err = self.folder.parent / f"example-{self.count:02d}.err"
        with open(out, "wb") as stdout, open(err, "wb") as stderr:
            process = subprocess.Popen(
                example,
                shell=True,
                executable="/bin/bash",
                cwd=self.folder,
                env=self.env,
                stdin=subprocess.DEVNULL,
                stdout=stdout,
                stderr=stderr,
                start_new_session=True,
            )
        self.sessions.append(process)
        return process, out, err

    @staticmethod
    def alive(process: subprocess.Popen) -> bool:
        """Whether a process of the example's session (its process group) still runs."""
        try:
            os.killpg(process.pid, 0)
        except ProcessLookupError:
            return False
        return True

    def gone(self, process: subprocess.Popen, within_s: float) -> bool:
        """Whether the example's session has no process left, waiting up to ``within_s``."""
        deadline = time.monotonic() + within_s
        while self.alive(process):
            if time.monotonic() > deadline:
                return False
            time.sleep(0.1)
        return True

    def finite(self, example: str) -> None:
        process, out, err = self.start(example)
        try:
            code = process.wait(timeout=ENDS_WITHIN_S)
        except subprocess.TimeoutExpired:
            pytest.fail(
                f"{example!r} did not end within {ENDS_WITHIN_S} s; if it runs until "
                "stopped, list it in NEVER_ENDING"
            )
        stderr = err.read_text(errors="replace")
        assert code == 0, f"{example!r} exited {code}:\n{stderr[-3000:]}"
        assert "Traceback" not in stderr, f"{example!r}:\n{stderr[-3000:]}"
        if example in BACKGROUND:
            assert self.alive(process), f"{example!r} left no service running"
        else:  # a pool's workers may take a moment to go after the command ended
            assert self.gone(process, LEAVES_WITHIN_S), (
                f"{example!r} left processes running {LEAVES_WITHIN_S} s after it ended; if "
                "that is its purpose, list it in BACKGROUND"
            )
        self.outputs[example] = out.read_text(errors="replace")

    def never_ending(self, example: str) -> None:
        kind, expected = NEVER_ENDING[example]
        process, out, err = self.start(example)
        deadline = time.monotonic() + UP_WITHIN_S
        while True:
            if kind == "file":
                target = self.folder / expected
                up = target.is_file() and target.stat().st_size > 0
            else:
                up = expected in out.read_text(errors="replace") + err.read_text(errors="replace")
            if up:
                break
            stderr = err.read_text(errors="replace")
            assert process.poll() is None, (
                f"{example!r} ended (exit code {process.returncode}) before it was up:\n"
                f"{stderr[-3000:]}"
            )
            assert time.monotonic() < deadline, (
                f"{example!r} was not up within {UP_WITHIN_S} s:\n{stderr[-3000:]}"
            )
            time.sleep(0.2)
        assert process.poll() is None, f"{example!r} ended by itself"
        os.killpg(process.pid, signal.SIGTERM)
        try:
            code = process.wait(timeout=60)
        except subprocess.TimeoutExpired:
            pytest.fail(f"{example!r} did not stop within 60 s of SIGTERM")
        stderr = err.read_text(errors="replace")
        assert code in STOPPED, f"{example!r} stopped with exit code {code}:\n{stderr[-3000:]}"
        assert "Traceback" not in stderr, f"{example!r}:\n{stderr[-3000:]}"
        assert self.gone(process, LEAVES_WITHIN_S), f"{example!r} left processes after it stopped"

    def stop_all(self) -> None:
        for process in self.sessions:
            for sent in (signal.SIGTERM, signal.SIGKILL):
                if not self.alive(process):
                    break
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(process.pid, sent)
                self.gone(process, 10)
            with contextlib.suppress(subprocess.TimeoutExpired):
                process.wait(timeout=10)


@contextlib.contextmanager
def machine_lock():
    """One run of this test at a time on this machine (the examples bind fixed ports)."""
    path = Path(tempfile.gettempdir()) / "wavemeter-help-examples.lock"
    with open(path, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


@pytest.mark.slow
def test_every_help_example_runs_in_order(tmp_path):
    """Each example exits 0 on the files the examples before it made, or, if it runs until
    stopped, is up and stops; the noise example reads every laser reading simulate wrote."""
    found = all_examples()
    folder = tmp_path / "work"
    folder.mkdir()
    runner = Runner(folder)
    ran = []
    with machine_lock():
        try:
            for _, example in found:
                if example in NEVER_ENDING:
                    runner.never_ending(example)
                else:
                    runner.finite(example)
                ran.append(example)
        finally:
            runner.stop_all()
    assert ran == [example for _, example in found]
    # simulate --laser wrote laser readings that noise read, every one of them
    laser_rows = len((folder / "laser.csv").read_text().splitlines()) - 1
    noise_json = next(
        output
        for example, output in runner.outputs.items()
        if example.startswith("wavemeter noise") and "--json" in example
    )
    analysis = json.loads(noise_json)
    assert laser_rows == 65536
    assert (analysis["n_readings"], analysis["n_excluded"]) == (laser_rows, 0)
    assert analysis["rate_hz"] == 10e6

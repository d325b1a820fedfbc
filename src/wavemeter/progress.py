"""Progress display for long command-line work, on stderr, never on stdout.

On a terminal: a transient rich bar with percentage, count, rate and time remaining where
the work is countable (:func:`progress_bar`, :func:`chunked`), a spinner where it is not
(:func:`busy`). Elsewhere (a log file, a pipe): one plain line every ``interval_s`` seconds
of long work, e.g. ``measuring data.csv: 45 % (450000/1000000 rows, 2.1e5 rows/s, ETA 3 s)``,
and nothing at all for work shorter than that. ``quiet`` silences both.
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from collections.abc import Callable, Iterator

__all__ = [
    "progress_bar",
    "progress_line",
    "chunked",
    "busy",
    "CHUNK_ROWS",
    "REPORT_INTERVAL_S",
    "shows_progress",
    "is_terminal",
]

#: rows handled per step of chunked work
CHUNK_ROWS = 1 << 17
#: seconds between plain progress lines when stderr is not a terminal
REPORT_INTERVAL_S = 5.0


def is_terminal(stream=None) -> bool:
    """Whether ``stream`` (default stderr) is a terminal."""
    stream = sys.stderr if stream is None else stream
    return bool(getattr(stream, "isatty", lambda: False)())


def shows_progress(quiet: bool = False, stream=None) -> bool:
    """Whether a bar or spinner would be drawn: not ``quiet`` and ``stream`` is a terminal."""
    return not quiet and is_terminal(stream)


def _short(value: float) -> str:
    """A number in two or three significant digits: ``2.1e5``, ``850``, ``0.5``."""
    if 0.1 <= abs(value) < 1e4:
        return f"{value:.3g}"
    return f"{value:.2g}".replace("e+0", "e").replace("e+", "e").replace("e-0", "e-")


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    minutes, seconds = divmod(round(seconds), 60)
    return f"{minutes} min {seconds} s" if minutes < 120 else f"{minutes / 60:.1f} h"


def progress_line(description: str, done: int, total: int, elapsed_s: float, unit: str) -> str:
    """The plain progress line: ``measuring x.csv: 45 % (450/1000 rows, 2.1e5 rows/s, ETA 3 s)``.

    Parameters
    ----------
    description : str
        What is being done.
    done, total : int
        Steps done and steps of the whole job.
    elapsed_s : float
        Seconds since the work started.
    unit : str
        What a step is (``"rows"``, ``"windows"``).
    """
    percent = 100 * done / total if total else 100.0
    parts = [f"{done}/{total} {unit}"]
    if elapsed_s > 0 and done > 0:
        rate = done / elapsed_s
        parts += [f"{_short(rate)} {unit}/s", f"ETA {_duration((total - done) / rate)}"]
    return f"{description}: {percent:.0f} % ({', '.join(parts)})"


def _rich_progress(stream, unit: str):
    """A transient rich Progress: description, bar, percentage, count, rate, time left."""
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        ProgressColumn,
        TaskProgressColumn,
        TextColumn,
        TimeRemainingColumn,
    )
    from rich.text import Text

    class RateColumn(ProgressColumn):
        """Steps per second, e.g. ``2.1e5 rows/s``."""

        def render(self, task):
            speed = task.finished_speed or task.speed
            return Text("" if speed is None else f"{_short(speed)} {unit}/s")

    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TaskProgressColumn(),
        MofNCompleteColumn(),
        TextColumn(unit),
        RateColumn(),
        TimeRemainingColumn(),
        console=Console(file=stream),
        transient=True,
    )


@contextlib.contextmanager
def progress_bar(
    description: str,
    total: int,
    *,
    quiet: bool = False,
    stream=None,
    unit: str = "rows",
    interval_s: float = REPORT_INTERVAL_S,
    clock: Callable[[], float] = time.monotonic,
) -> Iterator[Callable[[int], None]]:
    """Yield ``advance(steps)``: a rich bar on a terminal, plain lines on long work elsewhere.

    Parameters
    ----------
    description : str
        What is being done, e.g. ``"measuring data.csv"``.
    total : int
        Number of steps of the whole job.
    quiet : bool
        Show nothing.
    stream : file-like, optional
        Where progress goes (default ``sys.stderr``).
    unit : str
        What a step is, shown with the counts (``"rows"``).
    interval_s : float
        Off a terminal: seconds between plain lines; the first comes after this long.
    clock : callable
        Seconds, monotonic (a test passes a fake clock).
    """
    stream = sys.stderr if stream is None else stream
    if quiet:
        yield lambda steps: None
        return
    if is_terminal(stream):
        with _rich_progress(stream, unit) as progress:
            task = progress.add_task(description, total=total)
            yield lambda steps: progress.advance(task, steps)
        return
    start = clock()
    state = {"done": 0, "reported": start}

    def advance(steps: int) -> None:
        state["done"] += steps
        now = clock()
        if now - state["reported"] >= interval_s:
            state["reported"] = now
            line = progress_line(description, state["done"], total, now - start, unit)
            stream.write(line + "\n")
            stream.flush()

    yield advance


def chunked(
    rows: int,
    description: str,
    *,
    quiet: bool = False,
    chunk_rows: int = CHUNK_ROWS,
    stream=None,
    interval_s: float = REPORT_INTERVAL_S,
    clock: Callable[[], float] = time.monotonic,
) -> Iterator[slice]:
    """Slices covering ``range(rows)`` in chunks, advancing a :func:`progress_bar` after each.

    Parameters
    ----------
    rows : int
        Total number of rows.
    description : str
        What is being done.
    quiet : bool
        Show nothing.
    chunk_rows : int
        Rows per slice.
    stream : file-like, optional
        Where progress goes (default ``sys.stderr``).
    interval_s : float
        Off a terminal: seconds between plain lines.
    clock : callable
        Seconds, monotonic.
    """
    with progress_bar(
        description, rows, quiet=quiet, stream=stream, interval_s=interval_s, clock=clock
    ) as advance:
        for start in range(0, rows, chunk_rows):
            stop = min(start + chunk_rows, rows)
            yield slice(start, stop)
            advance(stop - start)


@contextlib.contextmanager
def busy(
    description: str, *, quiet: bool = False, stream=None, interval_s: float = REPORT_INTERVAL_S
) -> Iterator[None]:
    """Work of unknown length: a transient spinner on a terminal; elsewhere a line
    ``calibrating on x.csv: 10 s elapsed`` every ``interval_s`` seconds (none before).

    Parameters
    ----------
    description : str
        What is being done.
    quiet : bool
        Show nothing.
    stream : file-like, optional
        Where progress goes (default ``sys.stderr``).
    interval_s : float
        Off a terminal: seconds between plain lines.
    """
    stream = sys.stderr if stream is None else stream
    if quiet:
        yield
        return
    if is_terminal(stream):
        from rich.console import Console

        with Console(file=stream).status(description):
            yield
        return
    start = time.monotonic()
    done = threading.Event()

    def report() -> None:
        while not done.wait(interval_s):
            stream.write(f"{description}: {_duration(time.monotonic() - start)} elapsed\n")
            stream.flush()

    reporter = threading.Thread(target=report, name="wavemeter-busy", daemon=True)
    reporter.start()
    try:
        yield
    finally:
        done.set()
        reporter.join()

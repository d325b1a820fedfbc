"""Progress display for long command-line work: a bar on a terminal, silence elsewhere.

The bar goes to stderr, only when stderr is a terminal and the caller is not quiet, so
piped output, log files and tests see nothing. It disappears when the work is done.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator

__all__ = ["progress_bar", "chunked", "busy", "CHUNK_ROWS", "shows_progress"]

#: rows handled per step of chunked work
CHUNK_ROWS = 1 << 17


def shows_progress(quiet: bool = False, stream=None) -> bool:
    """Whether a bar would be drawn: not ``quiet`` and ``stream`` (default stderr) is a tty."""
    stream = sys.stderr if stream is None else stream
    return not quiet and bool(getattr(stream, "isatty", lambda: False)())


@contextlib.contextmanager
def progress_bar(
    description: str, total: int, *, quiet: bool = False, stream=None
) -> Iterator[Callable[[int], None]]:
    """Yield ``advance(steps)``; draw a transient rich bar when :func:`shows_progress`.

    Parameters
    ----------
    description : str
        What is being done, e.g. ``"measuring data.csv"``.
    total : int
        Number of steps (rows) of the whole job.
    quiet : bool
        Draw nothing.
    stream : file-like, optional
        Where the bar goes (default ``sys.stderr``).
    """
    if not shows_progress(quiet, stream):
        yield lambda steps: None
        return
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    console = Console(file=sys.stderr if stream is None else stream)
    columns = (TextColumn("{task.description}"), BarColumn(), TimeRemainingColumn())
    with Progress(*columns, console=console, transient=True) as progress:
        task = progress.add_task(description, total=total)
        yield lambda steps: progress.advance(task, steps)


def chunked(
    rows: int, description: str, *, quiet: bool = False, chunk_rows: int = CHUNK_ROWS, stream=None
) -> Iterator[slice]:
    """Slices covering ``range(rows)`` in chunks, advancing a progress bar after each.

    Parameters
    ----------
    rows : int
        Total number of rows.
    description : str
        Text beside the bar.
    quiet : bool
        Draw nothing.
    chunk_rows : int
        Rows per slice.
    stream : file-like, optional
        Where the bar goes (default ``sys.stderr``).
    """
    with progress_bar(description, rows, quiet=quiet, stream=stream) as advance:
        for start in range(0, rows, chunk_rows):
            stop = min(start + chunk_rows, rows)
            yield slice(start, stop)
            advance(stop - start)


@contextlib.contextmanager
def busy(description: str, *, quiet: bool = False, stream=None) -> Iterator[None]:
    """A transient spinner with ``description`` for work of unknown length (tty only)."""
    if not shows_progress(quiet, stream):
        yield
        return
    from rich.console import Console

    console = Console(file=sys.stderr if stream is None else stream)
    with console.status(description):
        yield

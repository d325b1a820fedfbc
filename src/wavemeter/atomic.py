"""Atomic file output: write to a temporary file beside the target, then rename."""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path

from .exceptions import InputError

__all__ = ["atomic_path", "check_output", "STDOUT"]

#: the output path that means standard output
STDOUT = "-"


def _umask() -> int:
    current = os.umask(0)
    os.umask(current)
    return current


def check_output(path, *, inputs=(), force: bool = False) -> None:
    """Refuse an output path that would destroy data or write where it must not.

    Parameters
    ----------
    path : str or Path
        The file to be written; ``"-"`` (standard output) is always allowed.
    inputs : sequence of str or Path
        Files the same command reads: the output must not be any of them, also not through
        a link or another name of the same file.
    force : bool
        Allow replacing an existing regular file.

    Raises
    ------
    InputError
        When the path is empty, is an input, is not a regular file (a folder, a device, a
        FIFO), exists and ``force`` is false, or its folder does not exist. ``parameter`` is
        ``"force"`` when allowing replacement would help.
    """
    if str(path) == STDOUT:
        return
    if not str(path):
        raise InputError("the output file name is empty: give a file name")
    target = Path(path)
    for source in inputs:
        if str(source) == STDOUT or not os.path.exists(source):
            continue
        if os.path.exists(target) and os.path.samefile(target, source):
            raise InputError(
                f"cannot write {target}: it is the input file {source}; writing it would "
                "destroy the input: choose another output name"
            )
    if os.path.lexists(target):
        mode = os.lstat(target).st_mode
        if stat.S_ISLNK(mode):
            mode = os.stat(target).st_mode if os.path.exists(target) else stat.S_IFREG
        if not stat.S_ISREG(mode):
            raise InputError(
                f"cannot write {target}: it exists and is not a regular file (a folder, device "
                "or pipe): choose a file name"
            )
        if not force:
            raise InputError(
                f"{target} already exists: choose another name, or allow replacing it",
                parameter="force",
            )
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"cannot write {target}: folder {folder} does not exist")


@contextlib.contextmanager
def atomic_path(path) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; on success rename it onto ``path``.

    On any exception the temporary file is removed and ``path`` is left untouched, so a
    failed write never leaves a partial output file.
    """
    target = Path(path)
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"cannot write {target}: folder {folder} does not exist")
    handle, temporary = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=folder)
    os.close(handle)
    os.chmod(temporary, 0o666 & ~_umask())  # mkstemp creates 0600; give the usual mode
    try:
        yield Path(temporary)
        os.replace(temporary, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
        raise

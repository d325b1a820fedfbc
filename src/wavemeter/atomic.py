"""Atomic file output: write to a temporary file beside the target, then rename."""

from __future__ import annotations

import contextlib
import os
import secrets
import stat
from collections.abc import Iterator
from pathlib import Path

from .exceptions import InputError

__all__ = ["atomic_path", "check_output", "STDOUT"]

#: the output path that means standard output
STDOUT = "-"


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

    On any exception, also ``KeyboardInterrupt`` and the ``SystemExit`` the command line
    raises on SIGTERM and SIGHUP, the temporary file is removed and ``path`` is left
    untouched, so a failed write never leaves a partial output file.

    Raises
    ------
    InputError
        When ``path`` is empty, is an existing folder, or its folder does not exist.
    """
    if not str(path):
        raise InputError("the output file name is empty: give a file name")
    target = Path(path)
    if target.is_dir():
        raise InputError(f"cannot write {target}: it is a folder; give a file name")
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"cannot write {target}: folder {folder} does not exist")
    # the name is chosen before the file exists, so that a signal arriving at any point
    # after the file is created finds it in the cleanup below (64 random bits: no clash)
    temporary = folder / f".{target.name}.{secrets.token_hex(8)}.tmp"
    try:
        # exclusive creation, mode 0666 less the umask, as an ordinary new file
        os.close(os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    except OSError as exc:  # a read-only folder, a full disk: about the output, not our name
        raise InputError(
            f"cannot write {target}: folder {folder} takes no new file "
            f"({(exc.strerror or type(exc).__name__).lower()}); choose a folder you can write to"
        ) from None
    try:
        yield temporary
        os.replace(temporary, target)
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
        if isinstance(exc, OSError) and str(temporary) in (exc.filename, exc.filename2):
            raise OSError(exc.errno, exc.strerror, str(target)) from None
        raise

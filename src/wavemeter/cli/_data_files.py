"""The data files a folder or a glob pattern names (``measure`` and ``fleet calibrate`` on
many files)."""

from __future__ import annotations

import glob
from pathlib import Path

from ..exceptions import InputError
from ..io.formats import FILE_FORMATS
from ._streams import is_stdio

__all__ = ["names_many_files", "data_files"]

#: characters that make DATA a glob pattern
_GLOB_CHARACTERS = frozenset("*?[")


def names_many_files(data) -> bool:
    """Whether DATA names many files: a folder, or a glob pattern that is no file."""
    if is_stdio(data):
        return False
    return Path(data).is_dir() or (
        not Path(data).exists() and bool(_GLOB_CHARACTERS & set(str(data)))
    )


def data_files(data) -> list[Path]:
    """The data files DATA names, in name order: a folder's files with a data extension
    (hidden files left out), or the files a glob pattern matches."""
    extensions = {ext for file_format in FILE_FORMATS for ext in file_format.extensions}
    if Path(data).is_dir():
        found = [
            path
            for path in Path(data).iterdir()
            if path.suffix.lower() in extensions and not path.name.startswith(".")
        ]
    else:
        found = [Path(name) for name in glob.glob(str(data))]
    files = sorted(path for path in found if path.is_file())
    if not files:
        what = "folder" if Path(data).is_dir() else "pattern"
        raise InputError(
            f"{data}: the {what} names no data file (extensions {', '.join(sorted(extensions))})"
        )
    return files

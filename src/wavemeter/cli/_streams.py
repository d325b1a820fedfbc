"""``-`` on the command line: stdin for a data file, stdout for an output.

The readers and the table writer take ``-`` themselves (:func:`wavemeter.io.read_table`,
:func:`wavemeter.io.write_table`); here is what the commands add: the name stdin goes by
in messages, and stdout for the other files they write (a calibration), written to a
temporary file first and copied to stdout only when complete, so that a failed command
writes nothing there.
"""

from __future__ import annotations

import contextlib
import shutil
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["STDIO", "STDIN_LABEL", "is_stdio", "output_path"]

#: the file name that means stdin (inputs) or stdout (outputs)
STDIO = "-"
#: how stdin is named in messages
STDIN_LABEL = "<stdin>"
_COPY_BYTES = 1 << 20


def is_stdio(path) -> bool:
    """Whether ``path`` is ``-`` (stdin for an input, stdout for an output)."""
    return str(path) == STDIO


@contextlib.contextmanager
def output_path(path) -> Iterator[Path]:
    """Yield the path to write ``path`` at; for ``-``, a temporary file copied to stdout
    after the block succeeds (and removed in any case)."""
    if not is_stdio(path):
        yield Path(path)
        return
    with tempfile.TemporaryDirectory(prefix="wavemeter-") as folder:
        temporary = Path(folder) / "output"
        yield temporary
        sys.stdout.flush()
        with open(temporary, "rb") as written:
            shutil.copyfileobj(written, sys.stdout.buffer, _COPY_BYTES)
        sys.stdout.buffer.flush()

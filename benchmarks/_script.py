"""What the benchmark scripts with a command line and a figure share: argument parsing that
reports bad input as one ``error:`` line (exit code 2), and figures written atomically as
256-colour PNG files."""

from __future__ import annotations

import argparse
import errno
import io
import os
from pathlib import Path

__all__ = ["Parser", "check_writable", "positive_int", "save_png", "temporary_path"]


class Parser(argparse.ArgumentParser):
    """Argument parser that reports bad input as one ``error:`` line and exit code 2."""

    def error(self, message: str):
        self.exit(2, f"error: {message}\n")


def positive_int(text: str) -> int:
    """An integer >= 1 (argparse type)."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return value


def temporary_path(path: Path) -> Path:
    """A hidden name next to ``path`` for writing it before renaming."""
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


def check_writable(path: Path) -> None:
    """Create the folder of ``path`` and probe it with a temporary file; raises OSError."""
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, "is a folder", str(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    probe = temporary_path(path)
    probe.touch()
    probe.unlink()


def save_png(figure, path: Path, dpi: int = 120) -> None:
    """Write a matplotlib figure to ``path`` as a 256-colour PNG, through a temporary name in
    the same folder renamed at the end: a failure leaves no partial figure."""
    from PIL import Image

    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi)
    buffer.seek(0)
    image = Image.open(buffer).convert("RGB").quantize(256)
    temporary = temporary_path(path)
    try:
        image.save(temporary, format="PNG", optimize=True)
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)

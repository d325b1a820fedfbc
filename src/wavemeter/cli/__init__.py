"""The ``wavemeter`` command line: one module per command, loaded when it runs."""

from .app import cli, main

__all__ = ["cli", "main"]

"""The package version, in one place (read by packaging, files and ``--version``)."""

__version__ = "0.7.1"

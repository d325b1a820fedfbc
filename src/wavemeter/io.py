"""Reading and writing tables of readings and results (file formats, columns, units)."""

from __future__ import annotations

import numpy as np

from .atomic import atomic_path

__all__ = ["write_table"]


def write_table(path, columns: dict[str, np.ndarray]) -> None:
    """Write named 1-D columns to a CSV file at full float64 precision, atomically.

    Parameters
    ----------
    path : str or Path
        Output file.
    columns : dict of str to array_like, each shape (N,)
        Column name (with its unit suffix, e.g. ``frequency_hz``) to values.
    """
    names = list(columns)
    data = np.column_stack([np.asarray(columns[name], dtype=float) for name in names])
    with atomic_path(path) as temporary:
        np.savetxt(temporary, data, delimiter=",", header=",".join(names), comments="", fmt="%.17g")

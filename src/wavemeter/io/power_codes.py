"""What a raw power reading that is no reading looks like: NaN or inf, a power meter's
"no reading" code, a dBm value no detector reads."""

from __future__ import annotations

import numpy as np

from ..units import SENTINEL_DBM

__all__ = ["SENTINEL_W", "MAX_DBM", "raw_power_problems"]

#: raw readings above this (any linear unit) are instrument "no reading" codes (9.91e37)
SENTINEL_W = 1e20
#: dBm readings above this (1 kW) are not a detector's reading: flagged invalid
MAX_DBM = 60.0


def raw_power_problems(raw: np.ndarray, unit: str | None) -> tuple[np.ndarray, ...]:
    """Masks of the raw power readings that are no reading: NaN/inf, power-meter
    sentinels, dBm above :data:`MAX_DBM`."""
    nonfinite = ~np.isfinite(raw)
    with np.errstate(invalid="ignore"):
        sentinel = raw > SENTINEL_W
        implausible = np.zeros_like(nonfinite)
        if unit == "dBm":
            sentinel |= raw <= SENTINEL_DBM
            implausible = (raw > MAX_DBM) & ~sentinel
    return nonfinite, sentinel, implausible

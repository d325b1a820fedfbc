"""What a calibration says of readings: the per-reading inputs in, the records out.

:class:`ReadingInputs` carries the inputs a calibrator may need besides the port powers
(``coarse_hz``, ``temperature_k``); :class:`Readout` is what
:meth:`~wavemeter.calibration.contract.reading.ReadingMixin.readout` gives for a block of
readings and :class:`StreamReading` what
:meth:`~wavemeter.calibration.contract.streaming.StreamMixin.stream` gives for one.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

__all__ = ["READING_INPUTS", "ReadingInputs", "Readout", "StreamReading"]

#: data a calibrator may require per reading, besides the port powers
READING_INPUTS = ("coarse_hz", "temperature_k")


@dataclass(frozen=True)
class ReadingInputs:
    """Per-reading inputs, each None (not given) or one value per reading.

    Attributes
    ----------
    coarse_hz : None or ndarray, shape (N,)
        Approximate frequency of each reading (Hz), within half an FSR.
    temperature_k : None or ndarray, shape (N,)
        Chip temperature of each reading (K).

    Examples
    --------
    >>> import numpy as np
    >>> from wavemeter.calibration import ReadingInputs
    >>> inputs = ReadingInputs(coarse_hz=np.array([193.40e12, 193.45e12]))  # no temperature given
    >>> inputs.coarse_hz.shape, inputs.temperature_k is None
    ((2,), True)
    """

    coarse_hz: np.ndarray | None = None
    temperature_k: np.ndarray | None = None

    def rows(self, rows) -> ReadingInputs:
        """The inputs of some readings (a boolean mask or indices)."""
        return ReadingInputs(
            *(
                None if value is None else value[rows]
                for value in (self.coarse_hz, self.temperature_k)
            )
        )

    def given(self) -> dict:
        """The given inputs by name, as keyword arguments of the reading methods."""
        return {
            name: value
            for name, value in (
                ("coarse_hz", self.coarse_hz),
                ("temperature_k", self.temperature_k),
            )
            if value is not None
        }

    def finite(self, samples: int) -> np.ndarray:
        """Whether every given input of each reading is a finite number (N,)."""
        ok = np.ones(samples, dtype=bool)
        for value in self.given().values():
            ok &= np.isfinite(value)
        return ok


@dataclass(frozen=True)
class Readout:
    """What a calibration found for a block of readings.

    Attributes
    ----------
    frequency_hz : ndarray, shape (N,)
        Source frequency (Hz); NaN for readings the calibration cannot read.
    frequency_std_hz : ndarray, shape (N,)
        Its standard deviation (Hz); NaN where the calibration gives none.
    flags : ndarray of int64, shape (N,)
        Quality bits (:class:`~wavemeter.calibration.contract.flags.ReadingFlag`).
    extras : dict of str to ndarray, shape (N,)
        The calibration's extra outputs (its ``reading_outputs``), by name.
    phase_rad : ndarray, shape (N,)
        The phase (rad) ``phase`` gives; NaN for readings the calibration cannot read.
    state : mapping
        What the calibration found of the block as a whole, for
        :meth:`~wavemeter.calibration.contract.base.BaseCalibrator.readout_notes` (a
        cascade: how much noisier than its sweep the readings are); empty for most.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> readout = cal.readout(powers[:3])
    >>> print(np.round((readout.frequency_hz - f_hz[:3]) / 1e6))  # MHz off the truth
    [-3.  6.  4.]
    >>> print(np.round(readout.frequency_std_hz / 1e6))  # each reading's stated std (MHz)
    [14. 14. 14.]
    >>> readout.flags.tolist(), readout.extras
    ([0, 0, 0], {})
    """

    frequency_hz: np.ndarray
    frequency_std_hz: np.ndarray
    flags: np.ndarray
    extras: dict = field(default_factory=dict)
    phase_rad: np.ndarray | None = None
    state: dict = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class StreamReading:
    """What a calibration found for one reading of a stream.

    Attributes
    ----------
    frequency_hz : float
        Source frequency (Hz), as ``predict`` gives it; NaN for a reading that cannot be read.
    frequency_std_hz : float
        Its standard deviation (Hz), as ``frequency_std_hz`` gives it; NaN where the
        calibration gives none or the reading cannot be read.
    flags : int
        Quality bits, as ``flags`` gives them; ``INVALID`` for a reading that cannot be read.
    extras : mapping of str to float
        The calibration's extra outputs (its ``reading_outputs``, e.g. a cascade's
        ``order_error_probability``), by name; NaN for a reading that cannot be read.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> for reading in cal.stream(powers[:2]):  # one reading at a time, as it arrives
    ...     f_thz, std_mhz = reading.frequency_hz / 1e12, reading.frequency_std_hz / 1e6
    ...     print(f"{f_thz:.6f} THz +- {std_mhz:.0f} MHz, flags {reading.flags}")
    193.374245 THz +- 14 MHz, flags 0
    193.374512 THz +- 14 MHz, flags 0
    """

    frequency_hz: float
    frequency_std_hz: float
    flags: int
    extras: Mapping[str, float] = field(default_factory=dict)

    @property
    def order_error_probability(self) -> float | None:
        """A cascade's ``extras["order_error_probability"]``; None for other calibrations."""
        return self.extras.get("order_error_probability")

"""The contract every calibrator keeps: what it declares and how it reads."""

from .base import CAPABILITIES, BaseCalibrator, Part
from .flags import ReadingFlag
from .records import READING_INPUTS, ReadingInputs, Readout, StreamReading

__all__ = [
    "BaseCalibrator",
    "CAPABILITIES",
    "Part",
    "READING_INPUTS",
    "ReadingFlag",
    "ReadingInputs",
    "Readout",
    "StreamReading",
]

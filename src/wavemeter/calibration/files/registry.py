"""Calibration-file tags and the classes they name.

Every calibrator class with a ``method`` tag of its own registers here when the class is
created (:meth:`wavemeter.calibration.contract.base.BaseCalibrator.__init_subclass__`); a second class
with the same tag is an error at import, so a tag always means one class. Loading a file
looks its tag up here: no walk over subclasses, no import of the classes from this module.
"""

from __future__ import annotations

from ...exceptions import WavemeterError

__all__ = ["register", "calibrator_class", "registered"]

_CLASSES: dict[str, type] = {}


def register(tag: str, cls: type) -> None:
    """Enter ``cls`` under ``tag``; raise when another class already holds the tag."""
    if not isinstance(tag, str) or not tag:
        raise WavemeterError(f"{cls.__qualname__}: a calibration tag must be a non-empty string")
    holder = _CLASSES.get(tag)
    if holder is not None and holder is not cls:
        raise WavemeterError(
            f"calibration tag {tag!r} of {cls.__module__}.{cls.__qualname__} is already used by "
            f"{holder.__module__}.{holder.__qualname__}: give the new class a tag of its own"
        )
    _CLASSES[tag] = cls


def calibrator_class(tag: str) -> type | None:
    """The class registered under ``tag``, or None."""
    return _CLASSES.get(tag) if isinstance(tag, str) else None


def registered() -> dict[str, type]:
    """A copy of the table: tag -> class, in registration order."""
    return dict(_CLASSES)

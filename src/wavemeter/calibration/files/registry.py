"""Calibration-file tags and the classes they name: built in, or from other packages.

Every calibrator class with a ``method`` tag of its own registers here when the class is
created (:meth:`wavemeter.calibration.contract.base.BaseCalibrator.__init_subclass__`); a
second class with the same tag is an error, so a tag always means one class. A package of
its own adds calibrators through the entry-point group ``wavemeter.calibrators``
(``ENTRY_POINT_GROUP``): each entry point is named by the tag and points at the class
(``toy = "wavemeter_toy:ToyCalibrator"``). Entry points are loaded lazily: one when its tag
is looked up and not built in, all of them when the list of methods is asked for.
"""

from __future__ import annotations

import warnings

from ...exceptions import CalibrationWarning, WavemeterError

__all__ = ["ENTRY_POINT_GROUP", "calibrator_class", "register", "registered"]

#: the entry-point group through which other packages add calibrators
ENTRY_POINT_GROUP = "wavemeter.calibrators"
#: the cause of the warning that a plug-in calibrator could not be loaded
PLUGIN_CAUSE = "plugin"

_CLASSES: dict[str, type] = {}
#: entry points already loaded (or refused), by name
_TRIED: set[str] = set()


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


def _entry_points():
    from importlib.metadata import entry_points

    return entry_points(group=ENTRY_POINT_GROUP)


def _load(point) -> type:
    """Import an entry point's calibrator (importing it registers it) and check that it is
    registered under the entry point's name."""
    _TRIED.add(point.name)
    where = f"entry point {point.name!r} = {point.value!r} of group {ENTRY_POINT_GROUP!r}"
    try:
        loaded = point.load()
    except Exception as exc:  # a broken plug-in: say which, and why
        raise WavemeterError(f"{where} cannot be loaded: {type(exc).__name__}: {exc}") from exc
    if _CLASSES.get(point.name) is not loaded:
        raise WavemeterError(
            f"{where} must name a calibrator class whose method tag is {point.name!r} (a "
            f"subclass of wavemeter.calibration.BaseCalibrator); it names {loaded!r}"
        )
    return loaded


def calibrator_class(tag: str) -> type | None:
    """The class registered under ``tag`` (loading its entry point when it is not built
    in), or None.

    Raises
    ------
    WavemeterError
        When the entry point of ``tag`` cannot be loaded or names no calibrator of that tag.

    Examples
    --------
    >>> from wavemeter.calibration import calibrator_class
    >>> calibrator_class("learned").__name__  # the tag a calibration file names
    'Calibrator'
    >>> calibrator_class("no_such_method") is None
    True
    """
    if not isinstance(tag, str):
        return None
    if tag not in _CLASSES and tag not in _TRIED:
        for point in _entry_points():
            if point.name == tag:
                return _load(point)
    return _CLASSES.get(tag)


def registered() -> dict[str, type]:
    """A copy of the table: tag -> class, the built-in ones in registration order, then
    those of the installed plug-ins (one that cannot be loaded is left out with a
    :class:`~wavemeter.exceptions.CalibrationWarning` saying why).

    Examples
    --------
    >>> from wavemeter.calibration import registered
    >>> table = registered()
    >>> table["learned"].__name__
    'Calibrator'
    >>> [tag for tag in table if tag in ("learned", "conventional", "wideband", "cascade")]
    ['conventional', 'learned', 'wideband', 'cascade']
    """
    for point in _entry_points():
        if point.name not in _CLASSES and point.name not in _TRIED:
            try:
                _load(point)
            except WavemeterError as exc:
                warnings.warn(
                    CalibrationWarning(
                        str(exc),
                        cause=PLUGIN_CAUSE,
                        remedy="reinstall or remove the package that declares it",
                    ),
                    stacklevel=2,
                )
    return dict(_CLASSES)

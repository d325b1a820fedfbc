"""The options of a calibration job, in library names and SI units, and the calibrator they make.

:class:`CalibrateOptions` is what ``wavemeter calibrate`` and ``wavemeter fleet calibrate``
are asked, and what :func:`wavemeter.jobs.calibrate_file` takes. :func:`build_calibrator`
turns them into an unfitted calibrator: it asks the registry for the method's class
(:func:`wavemeter.calibration.calibrator_class`, plug-ins included) and the class for its
settings (``get_params()`` of an unfitted instance). Every setting given is set on the
calibrator by name; one the method does not have is refused, naming the methods that have
it. A method whose default design FSR is a tuple (a cascade's stages) takes a tuple of
FSRs; the others take one. ``per_fsr`` fits a calibration set of the method, one per FSR
window. :func:`options_record` is what a calibration file keeps of the options
(``calibrate_options``): the calibrator's settings, every one, defaults included.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import InputError
from ..io import ColumnRequest
from ..units import frequency_text
from .sweeps import input_label

__all__ = [
    "CalibrateOptions",
    "build_calibrator",
    "method_class",
    "method_settings",
    "methods_offering",
    "methods_with",
    "options_record",
]


@dataclass(frozen=True)
class CalibrateOptions:
    """What to calibrate with, and how to read the sweep: library names, SI units.

    Attributes
    ----------
    method : str
        A calibration tag (:func:`wavemeter.calibration.registered`): ``"learned"``,
        ``"conventional"``, ``"thermal"``, ``"wideband"``, ``"cascade"``, a plug-in's.
    fsr_hz : float, tuple of float, or None
        Design FSR (Hz); for a method of stages (a cascade) one per stage, coarsest first.
        None: the method's default.
    fsr_tolerance : float, optional
        Relative half width of the FSR search (a setting of the method, or with
        ``per_fsr`` of the set's global search). None: the default.
    retrieval : str, optional
        Phase retrieval (``"pinv"``, ``"ml"``), a setting of the method. None: its default.
    settings : mapping of str to object
        Further settings of the method's calibrator, by name (``phase_order``,
        ``stage_ports``, ``temperature_std_k``, ``port_phases_rad``, ...).
    per_fsr : bool
        Fit one calibration of the method per FSR window of the sweep (a calibration set).
    request : ColumnRequest, optional
        Columns and units chosen by the user; the rest are found by name.
    drop_invalid : bool
        Skip invalid rows of the sweep (and of the dark readings) instead of failing.
    dark_w : tuple of float, optional
        Dark reading of each port (W), subtracted from every reading.
    dark_file : str or Path, optional
        A file of readings with the source off, averaged per port instead (``"-"``: stdin).
    temperature_k : tuple of float
        The chip temperature (K) of every reading of each sweep file, one per file, for a
        calibrator that needs it; empty: each file's temperature column.
    strict : bool
        A fit that warns is refused (:class:`~wavemeter.jobs.calibrate.CalibrationRefused`)
        and nothing is saved.

    Examples
    --------
    >>> from wavemeter.jobs import CalibrateOptions, build_calibrator
    >>> options = CalibrateOptions(method="wideband", fsr_hz=50e9, settings={"phase_order": 2})
    >>> calibrator = build_calibrator(options)  # unfitted, the method's settings applied
    >>> calibrator.method, calibrator.get_params()["phase_order"]
    ('wideband', 2)
    """

    method: str = "learned"
    fsr_hz: float | tuple[float, ...] | None = None
    fsr_tolerance: float | None = None
    retrieval: str | None = None
    settings: Mapping[str, object] = field(default_factory=dict)
    per_fsr: bool = False
    request: ColumnRequest | None = None
    drop_invalid: bool = False
    dark_w: tuple[float, ...] | None = None
    dark_file: str | None = None
    temperature_k: tuple[float, ...] = ()
    strict: bool = False

    @classmethod
    def from_keywords(cls, **keywords) -> CalibrateOptions:
        """Options from keywords: the fields by name, any other keyword a setting of the
        method (``CalibrateOptions.from_keywords(method="wideband", phase_order=2)``)."""
        names = {item.name for item in dataclasses.fields(cls)}
        given = {key: value for key, value in keywords.items() if key in names}
        settings = {key: value for key, value in keywords.items() if key not in names}
        return cls(**{**given, "settings": {**given.get("settings", {}), **settings}})

    def calibrator_settings(self) -> dict:
        """The settings given for the calibrator, by name (None left out)."""
        named = {"fsr_tolerance": self.fsr_tolerance, "retrieval": self.retrieval}
        return {
            **{key: value for key, value in named.items() if value is not None},
            **{key: value for key, value in self.settings.items() if value is not None},
        }


def method_class(method: str) -> type:
    """The calibrator class registered under ``method`` (plug-ins included).

    Raises
    ------
    InputError
        For a tag no class has (``parameter="method"``), listing those there are.
    """
    from ..calibration import calibrator_class, registered

    found = calibrator_class(method) if isinstance(method, str) else None
    if found is None:
        raise InputError(
            f"method {method!r} is not a calibration method; methods: {', '.join(registered())}",
            parameter="method",
        )
    return found


def method_settings(method: str) -> dict:
    """The settings of a method's calibrator with their defaults: ``get_params()`` of an
    unfitted one (``method_settings("cascade")["fsr_hz"]``: its stages' default FSRs).

    Examples
    --------
    >>> from wavemeter.jobs import method_settings
    >>> sorted(method_settings("learned").items())  # doctest: +NORMALIZE_WHITESPACE
    [('fsr_hz', 50000000000.0), ('fsr_tolerance', 0.2), ('retrieval', 'pinv'),
     ('search', 'golden'), ('xtol', 1e-12)]
    >>> [fsr_hz / 1e9 for fsr_hz in method_settings("cascade")["fsr_hz"]]  # stages, in GHz
    [5000.0, 500.0, 50.0]
    """
    return method_class(method)().get_params()


def methods_with(setting: str) -> list[str]:
    """The tags of the registered methods that have ``setting``."""
    from ..calibration import registered

    return [tag for tag, cls in registered().items() if setting in cls().get_params()]


def methods_offering(capability: str) -> list[str]:
    """The tags of the registered methods whose calibrators declare ``capability``."""
    from ..calibration import registered

    return [tag for tag, cls in registered().items() if capability in cls().capabilities]


def _takes_stages(defaults: dict) -> bool:
    """The method's default design FSR is a tuple: one per stage."""
    return np.ndim(defaults.get("fsr_hz")) == 1


def _design_fsr(options: CalibrateOptions, defaults: dict):
    """The design FSR to set (None: the default): one value, or a tuple for a method of
    stages (whose calibrator checks their count and order when it is fitted)."""
    if options.fsr_hz is None:
        return None
    values = tuple(np.atleast_1d(np.asarray(options.fsr_hz, dtype=object)).tolist())
    if _takes_stages(defaults):
        return values
    if len(values) != 1:
        from ..calibration import registered

        staged = [tag for tag, cls in registered().items() if _takes_stages(cls().get_params())]
        listed = ", ".join(frequency_text(value) for value in values)
        raise InputError(
            f"method {options.method!r} calibrates one interferometer: fsr_hz is its one "
            f"design FSR (Hz), got {len(values)} ({listed}); give one, or choose a method "
            f"with one design FSR per stage ({', '.join(staged)})",
            parameter="fsr_hz",
        )
    return values[0]


def _no_such_setting(method: str, name: str) -> InputError:
    having = methods_with(name)
    where = (
        f"it is a setting of {', '.join(having)}: leave it out, or choose a method that has it"
        if having
        else "no calibration method has it: leave it out"
    )
    return InputError(f"method {method!r} has no setting {name}; {where}", parameter=name)


def _check_window(calibrator, method: str) -> None:
    """``per_fsr``: the method reads one interferometer from the readings alone."""
    if calibrator.requires:
        why = f"also needs {', '.join(sorted(calibrator.requires))}"
    elif calibrator.absolute_frequency or _takes_stages(calibrator.get_params()):
        why = "reads the absolute frequency through stages of its own"
    else:
        return
    raise InputError(
        f"per_fsr calibrates each FSR window of the sweep with a method of one interferometer "
        f"that needs nothing but the readings; method {method!r} {why}: calibrate without "
        "per_fsr, or choose another method",
        parameter="per_fsr",
    )


def build_calibrator(options: CalibrateOptions):
    """The unfitted calibrator the options ask for (a calibration set with ``per_fsr``).

    Raises
    ------
    InputError
        For an unknown method (``parameter="method"``), a setting the method does not have
        (``parameter`` names it), several design FSRs for a method of one, a method that
        cannot be fitted per FSR window with ``per_fsr``.

    Examples
    --------
    >>> import wavemeter as wm
    >>> from wavemeter.jobs import CalibrateOptions, build_calibrator
    >>> build_calibrator(CalibrateOptions(fsr_hz=50e9, per_fsr=True)).method  # a set of windows
    'calibration_set'
    >>> try:  # a setting of another method is named, with the method that has it
    ...     build_calibrator(CalibrateOptions(method="learned", settings={"phase_order": 2}))
    ... except wm.InputError as error:
    ...     print(error.parameter, "-", str(error).split(";")[0])
    phase_order - method 'learned' has no setting phase_order
    """
    calibrator = method_class(options.method)()
    defaults = calibrator.get_params()
    if options.per_fsr:
        _check_window(calibrator, options.method)
    settings = options.calibrator_settings()
    fsr = _design_fsr(options, defaults)
    if fsr is not None:
        settings["fsr_hz"] = fsr
    for name, value in settings.items():
        if name in defaults:
            calibrator.set_params(**{name: value})
        elif not (options.per_fsr and name == "fsr_tolerance"):  # the set's global search
            raise _no_such_setting(options.method, name)
    if not options.per_fsr:
        return calibrator
    from ..calibration import CalibrationSet

    tolerance = settings.get("fsr_tolerance")
    return CalibrationSet(
        fsr_hz=calibrator.get_params()["fsr_hz"],
        window=calibrator,
        **({} if tolerance is None else {"fsr_tolerance": tolerance}),
    )


def _json_ready(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON-ready")


def options_record(options: CalibrateOptions, calibrator) -> dict:
    """What a calibration file keeps of the options (``calibrate_options``), as JSON reads
    it back (tuples as lists): the method, the calibrator's settings (every one, defaults
    included; a set's window as its method and settings), ``per_fsr``, the columns, the
    treatment of invalid rows, the dark readings and the temperatures given. Two runs
    with the same record make the same calibration of the same sweep.

    Raises
    ------
    InputError
        For a setting that is not a number, text, list or array.
    """
    # a set keeps its window as its method and settings; the others their settings as
    # given (JSON writes tuples as lists: a cascade's stage ports of unequal sizes too)
    settings = calibrator.get_params_for_file() if options.per_fsr else calibrator.get_params()
    record = {
        "method": options.method,
        "settings": settings,
        "per_fsr": options.per_fsr,
        "request": dataclasses.asdict(options.request or ColumnRequest()),
        "drop_invalid": options.drop_invalid,
        "dark_w": None if options.dark_w is None else list(options.dark_w),
        "dark_file": None if options.dark_file is None else input_label(options.dark_file),
        "temperature_k": list(options.temperature_k),
    }
    try:
        return json.loads(json.dumps(record, default=_json_ready, allow_nan=False))
    except (TypeError, ValueError) as exc:
        raise InputError(f"the calibration settings must be JSON-ready values: {exc}") from exc

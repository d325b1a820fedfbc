"""What a calibration needs of its readings: one set of checks for every job that reads.

``measure``, ``stream``, ``noise``, the fleet and the command line check readings against a
calibration with these functions alone, from what the calibration declares (``requires``,
``absolute_frequency``, ``capabilities``, its ports), never from its type:

- :func:`check_reading_options`, before the readings are opened: no coarse frequency for a
  calibration that does not use one (it reads within its FSR, or reads the absolute
  frequency), no temperature for one that does not use it, no per-reading uncertainty
  asked of one that gives none;
- :func:`check_readings`, against the columns the readings offer (a stream of chunks, a
  stream's header line): the calibration's ports, and a temperature and a coarse frequency
  where it needs them;
- :func:`check_ports`, the ports alone (for readings of known frequency too).

Messages name library parameters; a caller that names them otherwise (the command line,
its options) passes ``remedies``: parameter -> how to give what is missing.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..exceptions import InputError
from ..io import port_key

__all__ = [
    "REMEDIES",
    "TEMPERATURE_COLUMN_NAMES",
    "check_ports",
    "check_reading_options",
    "check_readings",
    "needs_temperature",
]

#: what a temperature column found by name looks like, for messages
TEMPERATURE_COLUMN_NAMES = "names like temperature_K, temp_C or 'Temp (C)', unit in the name"
#: how to give what the readings lack, in library parameters
REMEDIES = {
    "ports": "choose the port columns in the calibration's order (ports)",
    "temperature_k": "name the temperature column (temperature), or give one temperature for "
    "every reading (temperature_k)",
    "coarse_hz": "name the coarse column (coarse), or give one coarse frequency for every "
    "reading (coarse_hz)",
}


def needs_temperature(calibration) -> bool:
    """Whether ``calibration`` (fitted or not) needs the chip temperature of each reading."""
    return "temperature_k" in calibration.requires


def _is(calibration, name: str | None) -> str:
    """``chip.wmcal.json is a thermal calibration`` (``the calibration`` without a name)."""
    return f"{name or 'the calibration'} is a {calibration.method_label} calibration"


def _remedy(parameter: str, remedies: Mapping[str, str] | None) -> str:
    return (remedies or {}).get(parameter, REMEDIES[parameter])


def check_reading_options(
    calibration,
    *,
    name: str | None = None,
    coarse_column: str | None = None,
    coarse_hz=None,
    temperature_column: str | None = None,
    temperature_k=None,
    uncertainty: bool | None = None,
) -> None:
    """Before any reading: the inputs given are inputs the calibration uses.

    Parameters
    ----------
    calibration : BaseCalibrator
        The calibration the readings are for (fitted or not).
    name : str, optional
        The calibration as messages name it (its file).
    coarse_column, coarse_hz : optional
        A coarse-frequency column, or one coarse frequency for every reading (Hz).
    temperature_column, temperature_k : optional
        A temperature column, or the chip temperature (K) of every reading (a sequence:
        one per file, for a calibration's sweeps).
    uncertainty : bool, optional
        Each reading's standard deviation is asked for.

    Raises
    ------
    InputError
        ``parameter`` names the input refused.

    Examples
    --------
    >>> import wavemeter as wm
    >>> from wavemeter.jobs import check_reading_options
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(device.powers(f_hz, 1e-3, 5e-7, rng=1), f_hz)
    >>> check_reading_options(cal, uncertainty=True)  # a learned calibration states one
    >>> try:  # but reads within its FSR: a coarse frequency would go unused
    ...     check_reading_options(cal, coarse_hz=193.4e12)
    ... except wm.InputError as error:
    ...     print(error.parameter)
    coarse_hz
    """
    if calibration.absolute_frequency and (coarse_column is not None or coarse_hz is not None):
        parameter = "coarse" if coarse_column is not None else "coarse_hz"
        raise InputError(
            f"{_is(calibration, name)}: it reads the absolute frequency and picks every "
            f"fringe order itself, so it has no use for a coarse frequency; leave {parameter} out",
            parameter=parameter,
        )
    coarse_given = coarse_column is not None or coarse_hz is not None
    if (
        coarse_given
        and not calibration.absolute_frequency
        and "coarse_hz" not in calibration.requires
    ):
        parameter = "coarse" if coarse_column is not None else "coarse_hz"
        raise InputError(
            f"{parameter} gives a coarse frequency to a calibration that needs one to pick a "
            f"window or a fringe order (a set of windows, a wide band); {_is(calibration, name)}"
            f", which reads within its FSR and does not use it: leave {parameter} out",
            parameter=parameter,
        )
    given = temperature_k is not None and np.size(temperature_k) > 0
    if temperature_column is not None and given:
        raise InputError(
            "a temperature column (temperature) and temperature_k both give the chip "
            "temperature; give the column or the value, not both",
            parameter="temperature_k",
        )
    if not needs_temperature(calibration) and (given or temperature_column is not None):
        parameter = "temperature_k" if given else "temperature"
        raise InputError(
            f"{parameter} gives the chip temperature to a calibration that needs it "
            f"('temperature_k' in its requires: a thermal calibration); {_is(calibration, name)}, "
            f"which does not use it: leave {parameter} out",
            parameter=parameter,
        )
    if uncertainty and "frequency_std" not in calibration.capabilities:
        raise InputError(
            f"{_is(calibration, name)}, which gives no standard deviation of its readings "
            "('frequency_std' is not among its capabilities); uncertainty needs one that "
            "does (e.g. a learned calibration, single or per FSR)",
            parameter="uncertainty",
        )


def check_ports(
    calibration,
    source,
    *,
    explicit: bool = False,
    name: str | None = None,
    remedy: str | None = None,
) -> None:
    """The readings' ports are the calibration's: as many and, unless chosen explicitly,
    the same names (units aside).

    Parameters
    ----------
    calibration : BaseCalibrator
        A fitted calibration.
    source
        What the readings offer: ``source`` (their name) and ``port_names``.
    explicit : bool
        The port columns were chosen by the user (their names may differ).
    name : str, optional
        The calibration as messages name it.
    remedy : str, optional
        How to choose the ports, for the message (default: the parameter ``ports``).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import wavemeter as wm
    >>> from wavemeter.io import iter_readings, write_table
    >>> from wavemeter.jobs import check_ports
    >>> device = wm.Interferometer.table1(ports=3, seed=7)
    >>> f_hz = device.sweep_hz(200)
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)  # ports p1, p2, p3
    >>> path = Path(tempfile.mkdtemp()) / "readings.csv"
    >>> write_table(path, {f"p{k + 1}_w": powers[:5, k] for k in range(3)})
    >>> check_ports(cal, iter_readings(path))  # p1_w is p1 in W: the same ports
    >>> write_table(path, {f"p{k + 1}_w": powers[:5, k % 3] for k in range(4)})
    >>> try:
    ...     check_ports(cal, iter_readings(path))
    ... except wm.InputError as error:
    ...     print(str(error).split(" has ", 1)[1].split(";")[0])
    4 ports (p1_w, p2_w, p3_w, p4_w) but the calibration reads 3 (p1, p2, p3)
    """
    found = ", ".join(source.port_names)
    expected = ", ".join(calibration.port_names_)
    remedy = remedy or REMEDIES["ports"]
    calibrated = f"{name} was calibrated on" if name else "the calibration reads"
    if len(source.port_names) != calibration.n_ports_:
        raise InputError(
            f"{source.source} has {len(source.port_names)} ports ({found}) but {calibrated} "
            f"{calibration.n_ports_} ({expected}); {remedy}",
            parameter="ports",
        )
    keys = [port_key(port) for port in source.port_names]
    if not explicit and keys != [port_key(port) for port in calibration.port_names_]:
        raise InputError(
            f"{source.source} has ports {found} but {calibrated} ports {expected}; {remedy}",
            parameter="ports",
        )


def _coarse_missing(calibration, name: str | None, source, remedy: str) -> InputError:
    """The error for readings without the coarse frequency a calibration needs: what it
    reads (its parts, or its span) and why it needs one."""
    parts = calibration.parts()
    if parts:
        low = min(part.range_hz[0] for part in parts)
        high = max(part.range_hz[1] for part in parts)
        kind = parts[0].kind
        what = (
            f"{_is(calibration, name)} ({len(parts)} {kind}s, {low / 1e12:.6f} to "
            f"{high / 1e12:.6f} THz): it needs a coarse frequency per reading to pick the {kind}"
        )
    else:
        low, high = calibration.span_hz_
        what = (
            f"{_is(calibration, name)} ({low / 1e12:.6f} to {high / 1e12:.6f} THz, FSR "
            f"{calibration.fsr_hz_ / 1e9:.6f} GHz): it needs a coarse frequency per reading, "
            "within half an FSR of the truth (e.g. the laser set point), to pick the fringe order"
        )
    return InputError(
        f"{what}, and {source.source} has no coarse column; {remedy}", parameter="coarse_hz"
    )


def check_readings(
    calibration,
    source,
    *,
    coarse_hz=None,
    temperature_k=None,
    ports_given: bool = False,
    name: str | None = None,
    remedies: Mapping[str, str] | None = None,
) -> None:
    """The readings ``source`` offer what the calibration needs, before any is read.

    Parameters
    ----------
    calibration : BaseCalibrator
        A fitted calibration.
    source
        What the readings offer: ``source`` (their name), ``port_names``,
        ``temperature_column`` and ``coarse_column`` (a
        :class:`~wavemeter.io.ReadingStream`, a stream's header).
    coarse_hz, temperature_k : optional
        One coarse frequency (Hz) / chip temperature (K) for every reading, instead of a
        column.
    ports_given : bool
        The port columns were chosen by the user.
    name : str, optional
        The calibration as messages name it (its file).
    remedies : mapping of str to str, optional
        How to give what is missing, by parameter (``ports``, ``temperature_k``,
        ``coarse_hz``), for a caller that names them otherwise (:data:`REMEDIES`).

    Raises
    ------
    InputError
        Other ports than the calibration's (``parameter="ports"``), no temperature for a
        calibration that needs it (``"temperature_k"``), no coarse frequency for one that
        needs it (``"coarse_hz"``), a coarse column for one that reads the absolute
        frequency (``"coarse"``).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> from wavemeter.io import iter_readings, write_table
    >>> from wavemeter.jobs import check_readings
    >>> chip = wm.Interferometer.table1(ports=3, seed=7).with_thermal("sin")
    >>> temperatures_k = np.repeat([293.0, 295.0], 200)  # two sweeps, 2 K apart
    >>> f_hz = np.tile(chip.sweep_hz(200), 2)
    >>> powers = chip.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1, temperature_k=temperatures_k)
    >>> thermal = wm.ThermalCalibrator(fsr_hz=50e9).fit(powers, f_hz, temperature_k=temperatures_k)
    >>> path = Path(tempfile.mkdtemp()) / "readings.csv"
    >>> write_table(path, {f"p{k + 1}_w": powers[:5, k] for k in range(3)})  # no temperature
    >>> try:  # refused before any reading is read
    ...     check_readings(thermal, iter_readings(path))
    ... except wm.InputError as error:
    ...     print(error.parameter)
    temperature_k
    >>> check_readings(thermal, iter_readings(path), temperature_k=294.0)  # one for the file
    """
    check_ports(
        calibration,
        source,
        explicit=ports_given,
        name=name,
        remedy=_remedy("ports", remedies),
    )
    if needs_temperature(calibration) and temperature_k is None:
        if source.temperature_column is None:
            raise InputError(
                f"{_is(calibration, name)}: it needs the chip temperature of each reading, and "
                f"{source.source} has no temperature column (looked for "
                f"{TEMPERATURE_COLUMN_NAMES}); {_remedy('temperature_k', remedies)}",
                parameter="temperature_k",
            )
    if "coarse_hz" in calibration.requires:
        if coarse_hz is None and source.coarse_column is None:
            raise _coarse_missing(calibration, name, source, _remedy("coarse_hz", remedies))
    else:
        check_reading_options(
            calibration, name=name, coarse_column=source.coarse_column, coarse_hz=coarse_hz
        )

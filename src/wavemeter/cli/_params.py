"""What options accept: physical quantities with units, the orders of a wide-band model,
the stages of a cascade, and old option names kept hidden.

Every physical quantity on the command line is a number with a unit (``50GHz``, ``1 mW``,
``-30dBm``, ``1550nm``, ``20C``); a bare number is in SI units (Hz, W, K). A bare frequency
below 1 MHz is refused as a probable missing unit before any work starts.
"""

from __future__ import annotations

import contextlib
import math
import re
from collections import Counter

import click

from ..exceptions import InputError
from ..units import (
    OPTICAL_BAND_HZ,
    SPEED_OF_LIGHT_M_S,
    canonical_unit,
    parse_frequency_hz,
    parse_optical_frequency_hz,
    parse_power_w,
    parse_quantity,
    parse_time_s,
    temperature_to_k,
)

__all__ = [
    "AliasedOption",
    "FrequencyParam",
    "OpticalFrequencyParam",
    "PowerParam",
    "PowerListParam",
    "TemperatureParam",
    "OrderParam",
    "FrequencyListParam",
    "BandParam",
    "StagePortsParam",
    "DelimiterParam",
    "FREQUENCY",
    "FSR",
    "OPTICAL_FREQUENCY",
    "POWER",
    "NOISE_POWER",
    "OFFSETS",
    "NOISE_POWERS",
    "TEMPERATURE",
    "PHASE_ORDER",
    "MAP_ORDER",
    "FSRS",
    "BAND",
    "STAGE_PORTS",
    "DELIMITER",
    "BARE_FREQUENCY_LIMIT_HZ",
]

#: a bare number below this, given for a frequency, is taken as a missing unit
BARE_FREQUENCY_LIMIT_HZ = 1e6


class AliasedOption(click.Option):
    """An option whose old names still work but are not shown in ``--help`` or errors.

    Parameters
    ----------
    hidden_aliases : sequence of str
        Old option names (e.g. ``"--power-w"``), also listed among the declarations.
    """

    def __init__(self, *args, hidden_aliases=(), **kwargs):
        super().__init__(*args, **kwargs)
        self.hidden_aliases = frozenset(hidden_aliases)

    @contextlib.contextmanager
    def _shown_names(self):
        opts = self.opts
        self.opts = [name for name in opts if name not in self.hidden_aliases]
        try:
            yield
        finally:
            self.opts = opts

    def get_help_record(self, ctx):
        with self._shown_names():
            return super().get_help_record(ctx)

    def get_error_hint(self, ctx):
        with self._shown_names():
            return super().get_error_hint(ctx)


class FrequencyParam(click.ParamType):
    """A frequency with a unit: ``50GHz``, ``49.69 GHz``; a bare number is in Hz.

    Parameters
    ----------
    quantity : str, optional
        What the frequency is, for the missing-unit message (``"an FSR an optical
        interferometer has"``); None accepts any bare number.
    likely_unit : str
        The unit a bare number probably missed (``"GHz"``), suggested in that message.
    """

    name = "FREQUENCY"

    def __init__(self, quantity: str | None = None, likely_unit: str = "GHz"):
        self.quantity = quantity
        self.likely_unit = likely_unit

    def convert(self, value, param, ctx):
        if isinstance(value, float):
            return value
        try:
            number, unit = parse_quantity(value, "frequency", "value")
            frequency_hz = parse_frequency_hz(value, "value")
        except InputError as exc:
            self.fail(str(exc), param, ctx)
        if self.quantity is None:
            return frequency_hz
        if unit is None and abs(number) < BARE_FREQUENCY_LIMIT_HZ:
            self.fail(
                f"{value} is a bare number, so in Hz; {number:g} Hz is not {self.quantity}; "
                f"did you mean {number:g}{self.likely_unit}?",
                param,
                ctx,
            )
        if not frequency_hz > 0:
            self.fail(f"{value}: must be > 0", param, ctx)
        return frequency_hz


class OpticalFrequencyParam(click.ParamType):
    """An optical frequency or vacuum wavelength: ``193.4THz``, ``1550nm``; bare: Hz."""

    name = "FREQUENCY"

    def convert(self, value, param, ctx):
        if isinstance(value, float):
            return value
        try:
            number, unit = parse_quantity(value, "axis", "value")
            frequency_hz = parse_optical_frequency_hz(value, "value")
        except InputError as exc:
            self.fail(str(exc), param, ctx)
        low, high = OPTICAL_BAND_HZ
        if low <= frequency_hz <= high:
            return frequency_hz
        if unit is None:
            guesses = [
                guess
                for guess, hz in (("THz", number * 1e12), ("nm", SPEED_OF_LIGHT_M_S / number * 1e9))
                if number > 0 and low <= hz <= high
            ]
            hint = f"did you mean {number:g}{guesses[0]}?" if guesses else "write the unit"
            self.fail(
                f"{value} is a bare number, so in Hz; {number:g} Hz is not an optical "
                f"frequency; {hint}",
                param,
                ctx,
            )
        self.fail(f"{value} is not an optical frequency (100-1000 THz, 300-3000 nm)", param, ctx)


class PowerParam(click.ParamType):
    """A power: ``1mW``, ``5e-7 W``, ``-30dBm``; a bare number is in W.

    Parameters
    ----------
    allow_zero : bool
        Whether 0 W is allowed (a noise level), else the power must be > 0.
    """

    name = "POWER"

    def __init__(self, allow_zero: bool = False):
        self.allow_zero = allow_zero

    def convert(self, value, param, ctx):
        if isinstance(value, float):
            return value
        try:
            power_w = parse_power_w(value, "value")
        except InputError as exc:
            self.fail(str(exc), param, ctx)
        if power_w < 0 or (power_w == 0 and not self.allow_zero):
            bound = ">= 0" if self.allow_zero else "> 0"
            self.fail(f"{value}: must be {bound}", param, ctx)
        return power_w


class PowerListParam(click.ParamType):
    """Powers separated by commas: ``1uW``, ``'2e-7,0,1nW'``; a bare number is in W.

    Converts to a tuple of float (W).

    Parameters
    ----------
    signed : bool
        Offsets (dark readings) may be negative, and dBm, which names only positive
        powers, is refused for them; otherwise (noise levels) each must be >= 0.
    """

    name = "W,W,.."

    def __init__(self, signed: bool):
        self.signed = signed

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        powers_w = []
        for text in str(value).split(","):
            try:
                _, unit = parse_quantity(text, "power", "value")
                if self.signed and unit == "dBm":
                    raise InputError(
                        f"{text.strip()}: dBm names only positive powers, and an offset is "
                        "signed; give W, mW, uW or nW (e.g. -20nW)"
                    )
                powers_w.append(parse_power_w(text, "value"))
            except InputError as exc:
                self.fail(str(exc), param, ctx)
        if not self.signed and min(powers_w) < 0:
            self.fail(f"{value}: each must be >= 0", param, ctx)
        return tuple(powers_w)


_TEMPERATURE_TEXT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(\S.*?)?\s*$")


class TemperatureParam(click.ParamType):
    """A chip temperature: ``293.15``, ``293.15K``, ``20C``, ``20 degC``; a bare number is in K.

    Converts to float (K); the result must be a finite temperature above 0 K.
    """

    name = "TEMPERATURE"

    def convert(self, value, param, ctx):
        if isinstance(value, float):
            return value
        found = _TEMPERATURE_TEXT.match(str(value))
        if found is None:
            self.fail(
                f"{value!r} is not a temperature: give a number in K (293.15), or with its "
                "unit K or C (293.15K, 20C)",
                param,
                ctx,
            )
        number, unit = found.groups()
        try:
            unit = canonical_unit(unit or "K", "temperature", str(value).strip())
        except InputError as exc:
            self.fail(str(exc), param, ctx)
        temperature_k = float(temperature_to_k(float(number), unit))
        if not (math.isfinite(temperature_k) and temperature_k > 0):
            self.fail(f"{value}: a temperature must be a finite number above 0 K", param, ctx)
        return temperature_k


class DurationParam(click.ParamType):
    """A duration: ``1ms``, ``2.5 s``, ``10us``; a bare number is in s. Converts to s (> 0)."""

    name = "TIME"

    def convert(self, value, param, ctx):
        if isinstance(value, float):
            return value
        try:
            seconds = parse_time_s(value, str(value).strip())
        except InputError as exc:
            self.fail(str(exc), param, ctx)
        if not seconds > 0:
            self.fail(f"{value}: must be a finite time > 0", param, ctx)
        return seconds


class OrderParam(click.ParamType):
    """An order of the wide-band model: an integer from ``lowest`` to the calibration's
    highest (looked up when a value is given, so that ``--help`` imports no numerics).

    Parameters
    ----------
    lowest : int
        Smallest order allowed.
    highest_name : str
        Name of the constant in :mod:`wavemeter.calibration.models.wideband_orders` holding the
        highest order allowed (``"MAX_PHASE_ORDER"``).
    """

    name = "ORDER"

    def __init__(self, lowest: int, highest_name: str):
        self.lowest = lowest
        self.highest_name = highest_name

    def convert(self, value, param, ctx):
        from ..calibration.models import wideband_orders

        highest = getattr(wideband_orders, self.highest_name)
        text = str(value).strip()
        if isinstance(value, int) and not isinstance(value, bool):
            order = value
        elif re.fullmatch(r"[+-]?\d+", text):
            order = int(text)
        else:
            order = None
        if order is None or not self.lowest <= order <= highest:
            self.fail(
                f"must be an integer from {self.lowest} to {highest} (leave it out to choose "
                f"it by cross-validation), got {text!r}",
                param,
                ctx,
            )
        return order


class FrequencyListParam(click.ParamType):
    """Frequencies separated by commas, each as ``item`` takes it: ``5THz,500GHz,50GHz``.

    Converts to a tuple of float (Hz), in the order given.

    Parameters
    ----------
    item : FrequencyParam
        What each frequency must be (an FSR refuses a bare number below 1 MHz).
    """

    name = "F,F,.."

    def __init__(self, item: FrequencyParam):
        self.item = item

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        parts = [part.strip() for part in str(value).split(",")]
        if not all(parts):
            self.fail(
                f"{value!r}: empty value; separate frequencies with single commas", param, ctx
            )
        return tuple(self.item.convert(part, param, ctx) for part in parts)


class BandParam(click.ParamType):
    """An optical band ``LOW:HIGH``, each an optical frequency or vacuum wavelength
    (``191THz:195.4THz``, ``1534nm:1570nm``). Converts to ``(low, high)`` in Hz, low first."""

    name = "LOW:HIGH"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        parts = str(value).split(":")
        if len(parts) != 2:
            self.fail(
                f"{value!r} is not a band: give its ends as LOW:HIGH (191THz:195.4THz)", param, ctx
            )
        ends = sorted(OPTICAL_FREQUENCY.convert(part.strip(), param, ctx) for part in parts)
        if not ends[1] > ends[0]:
            self.fail(f"{value!r}: the band's ends must differ", param, ctx)
        return tuple(ends)


_POSITIONS = re.compile(r"^(\d+)(?:-(\d+))?$")
#: the highest column position ``--stage-ports`` takes (far above any reading's port count)
MAX_COLUMN_POSITION = 4096


def _positions(token: str) -> range | None:
    """Column positions of one token, ``3`` or ``4-6`` (from 1), or None if it is not one."""
    found = _POSITIONS.match(token.strip())
    if found is None:
        return None
    first = int(found.group(1))
    last = first if found.group(2) is None else int(found.group(2))
    if not 1 <= first <= last <= MAX_COLUMN_POSITION:
        return None
    return range(first, last + 1)


class StagePortsParam(click.ParamType):
    """The port columns of each stage of a cascade: stages separated by ``/``, each a list of
    positions among the port columns (counted from 1, in the order the columns are read)
    and ranges ``A-B``: ``1-3/4-6/7-9``, ``1,3,5/2,4,6/7-9``.

    Converts to a tuple with one tuple of positions (from 1) per stage. A column given to
    two stages is refused here; whether every column belongs to a stage, and the stages
    match the FSRs, is checked against the file.
    """

    name = "A-B/C-D/.."

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        stages = []
        for text in str(value).split("/"):
            positions = []
            for token in text.split(","):
                found = _positions(token)
                if found is None:
                    self.fail(
                        f"{value!r}: {token.strip()!r} is not a column position or range; give "
                        "each stage's columns by position from 1 (3 or 4-6), stages separated by "
                        "'/': 1-3/4-6/7-9",
                        param,
                        ctx,
                    )
                positions += found
            stages.append(tuple(positions))
        counts = Counter(position for stage in stages for position in stage)
        twice = sorted(position for position, count in counts.items() if count > 1)
        if twice:
            self.fail(
                f"{value!r} gives column(s) {', '.join(map(str, twice))} to more than one stage; "
                "each port column belongs to one stage",
                param,
                ctx,
            )
        return tuple(stages)


class DelimiterParam(click.ParamType):
    """The column delimiter of text input: one character (``,`` ``;`` ``|``), or ``tab``
    (also ``\t``) or ``space`` (runs of spaces and tabs). Converts to the character
    (``" "`` for space); whether a text table can have it is checked by the reader."""

    name = "CHAR"
    _NAMED = {"tab": "\t", "\\t": "\t", "space": " ", "comma": ",", "semicolon": ";"}

    def convert(self, value, param, ctx):
        text = str(value)
        delimiter = self._NAMED.get(text.strip().lower(), text)
        if len(delimiter) != 1:
            self.fail(
                f"{text!r} is not one character: give the delimiter as one character (, ; |), "
                "or tab or space",
                param,
                ctx,
            )
        return delimiter


#: any frequency; a bare number is in Hz
FREQUENCY = FrequencyParam()
#: a free spectral range: refuses a bare number below 1 MHz (``--fsr 50`` meant 50GHz)
FSR = FrequencyParam("an FSR an optical interferometer has", "GHz")
#: an optical frequency (100-1000 THz) given as a frequency or a vacuum wavelength
OPTICAL_FREQUENCY = OpticalFrequencyParam()
#: a source power (> 0)
POWER = PowerParam()
#: a noise standard deviation in power (>= 0)
NOISE_POWER = PowerParam(allow_zero=True)
#: signed per-port power offsets (dark readings), W
OFFSETS = PowerListParam(signed=True)
#: per-port noise standard deviations (>= 0), W
NOISE_POWERS = PowerListParam(signed=False)
#: a chip temperature (K) given as K or C; a bare number is in K
TEMPERATURE = TemperatureParam()
#: a duration (s), > 0
DURATION = DurationParam()
#: phase order P of a wide-band calibration, 1 (linear phase) to the highest searched
PHASE_ORDER = OrderParam(1, "MAX_PHASE_ORDER")
#: map order J of a wide-band calibration, 0 (one map) to the highest searched
MAP_ORDER = OrderParam(0, "MAX_MAP_ORDER")
#: the design FSRs of a cascade's stages, coarsest first (each as ``FSR`` takes it)
FSRS = FrequencyListParam(FSR)
#: an optical band LOW:HIGH (Hz)
BAND = BandParam()
#: the port columns of each stage of a cascade (positions from 1)
STAGE_PORTS = StagePortsParam()
#: the column delimiter of text input
DELIMITER = DelimiterParam()

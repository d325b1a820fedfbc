"""What ``wavemeter simulate`` records, as a library object: :class:`Scenario`.

A scenario is a simulated device (a Table 1 interferometer, with hardware faults, thermal
or wide-band behaviour, or a cascade of them) and what is recorded with it: a calibration
sweep, test readings at random frequencies, a laser record, dark readings. ``Scenario(...)
.tables()`` gives the sweep and test columns ``wavemeter simulate`` writes for the same
options, value for value, ``laser_table()`` the laser record and ``dark_table()`` the dark
readings, so a ``--seed`` run is reproduced from Python.
Its random streams: :mod:`~wavemeter.simulation.scenario_defaults`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..units import hz_to_axis
from . import scenario_checks as checks
from .cascade import CascadeInterferometer
from .cell_recording import CELL_COLUMN, TRUE_COLUMN, cell_sweep, check_cell
from .drift import slow_power_drift, thermal_ramp_rad
from .interferometer import DEFAULT_FSR_HZ, Interferometer
from .laser import laser_frequency_hz
from .recording import axis_column, readings
from .scenario_defaults import (
    DARK_STREAM,
    DEFAULT_CASCADE_BAND_HZ,
    DEFAULT_LASER_RATE_HZ,
    DEFAULT_NOISE_W,
    DEFAULT_POWER_W,
    DEFAULT_SPAN_FSR,
    DEFAULT_THERMAL_RAD_PER_K,
    DRIFT_STREAM,
    LASER_STREAM,
    SPECTRAL_STREAM,
    TEMPERATURE_STREAM,
)
from .spectral_presets import SPECTRAL_PRESETS, SpectralPreset

__all__ = ["Scenario"]

#: scenario fields -> the SpectralPreset fields they replace
_SPECTRAL_FIELDS = {
    "dispersion_s2": "dispersion_s2",
    "coupler_slope_sigma_per_thz": "coupler_slope_sigma_per_thz",
    "responsivity_slope_sigma_per_thz": "responsivity_slope_sigma_per_thz",
}


@dataclass(frozen=True)
class Scenario:
    """A simulated device and its recordings: what ``wavemeter simulate`` writes.

    Every field is checked when the scenario is made (and the device drawn: a spectral slope
    that takes a responsivity to zero within the sweep is refused too), so a scenario that
    exists can be recorded. Fields left None are not set: a cascade refuses the single
    device's settings only when they are set.

    Parameters
    ----------
    ports : int
        Output ports of the MMI (of each stage of a cascade), 3 to 64.
    seed : int
        Seed (>= 0) of the device impairments and the noise.
    samples : int
        Readings in one calibration sweep (>= 4).
    span_fsr : float, optional
        Sweep span in true FSRs about the device centre (> 0; None: 1).
    power_w : float
        Source power (W), > 0 (a cascade's before the split).
    noise_w : float, optional
        Detector noise std per reading (W), >= 0 (None: 5e-7 W, or ``port_noise_w``).
    fsr_hz : float, optional
        Design FSR (Hz), > 0 (None: 50 GHz); the device's differs by Table 1's delay spread.
    cascade_fsrs_hz : sequence of float, optional
        Simulate a cascade of Table 1 stages of these design FSRs (Hz), coarsest first,
        fed by one source through an equal splitter and swept over ``band_hz``.
    band_hz : (float, float), optional
        Band (Hz) a cascade's sweep covers, evenly, ends included (None: the C band,
        191-195.4 THz); its stages are centred in it.
    test : int
        Test readings at frequencies uniform over the sweep, with the truth column (0: none).
    x_unit : str
        Unit of the axis column: Hz..THz (``frequency_<unit>``) or nm, um, m
        (``wavelength_<unit>``).
    power_unit : str
        Unit of the port and monitor columns: W, mW, uW, nW or dBm.
    power_fluctuation : float
        Relative std of the source power per reading, in [0, 0.3]; > 0 adds a monitor.
    dark_offset_w : float or sequence of float, optional
        Fault: detector dark/ADC offset (W) of every port, or of each; every recording.
    port_noise_w : sequence of float, optional
        Fault: detector noise std (W) of each port, instead of ``noise_w``.
    dispersion_s2 : float, optional
        Fault: group-delay dispersion of the delay imbalance (s^2; None: the spectral
        platform's, or 0).
    spectral : str, optional
        Wide-band platform (``"sin"``): its dispersion and random spectral slopes of the
        coupler entries and responsivities, drawn from the seed.
    coupler_slope_sigma_per_thz, responsivity_slope_sigma_per_thz : float, optional
        Sigma (1/THz), >= 0, of the random relative slopes of the coupler entries and of
        each responsivity, replacing the platform's (a platform of zeros without one).
    power_drift : float
        Fault: peak relative excursion of a slow source-power drift over the sweep, in
        [0, 1); > 0 adds a monitor. Sweep only.
    thermal_drift_k : float, optional
        Fault: chip temperature rise (K) over the sweep, a linear ramp from 0 moving the
        bias phase at the device's thermal coefficient (``DEFAULT_THERMAL_RAD_PER_K``
        without one); no temperature column. Sweep only.
    platform : str, optional
        Thermal platform (``"sin"``, ``"soi"``): the recordings get ``temperature_k``.
    temperature_k : float, optional
        Chip temperature (K) of every recording (None: the device's reference, 293.15 K).
    ramp_k : (float, float), optional
        Chip temperature ramping linearly from the first to the second (K) over the sweep
        and over the laser record; the test readings at temperatures uniform over it.
    repeat : int
        Sweeps recorded in a row (>= 1).
    monitor : bool
        Write the monitor column when the source power varies.
    laser : int
        Readings of the laser record (0: none), a column ``time_s`` (s) first.
    laser_rate_hz : float, optional
        Its sample rate (Hz), > 0 (None: 10 MHz).
    laser_center_hz : float, optional
        The laser's frequency at the start (Hz; None: the device centre).
    white_fm_hz2_per_hz, flicker_fm_hz2, random_walk_fm_hz2_per_s : float
        The laser's white, flicker and random-walk FM levels ``h0, h_-1, h_-2``
        (Hz^2/Hz, Hz^2, Hz^2/s), >= 0 (see :func:`~wavemeter.simulation.laser_frequency_hz`).
    laser_drift_hz_per_s : float
        The laser's linear drift (Hz/s).
    dark : int
        Readings with the source off (0: none): the detectors' dark offset and noise.
    sweep_axis : str, optional
        A :data:`~wavemeter.simulation.SWEEP_PRESETS` key: the sweep's axis column is what
        that laser records, and ``simulated_true_frequency_hz`` (Hz) the truth the meter
        saw, for evaluation only (:mod:`~wavemeter.simulation.cell_recording`).
    reference_cell : str, optional
        A :data:`~wavemeter.simulation.CELL_PRESETS` key or a line table file: a
        ``cell_transmission`` column, the cell recorded beside the ports at the true
        frequencies (with ``simulated_true_frequency_hz`` too).

    Raises
    ------
    InputError
        For a value out of its range or fields that exclude one another, with
        ``parameter`` naming the field to change.

    Examples
    --------
    >>> from wavemeter.simulation import Scenario
    >>> scenario = Scenario(samples=5, test=2, seed=1)
    >>> sweep, test = scenario.tables()
    >>> list(sweep), list(test)
    (['frequency_hz', 'p1_w', 'p2_w', 'p3_w'], ['true_frequency_hz', 'p1_w', 'p2_w', 'p3_w'])
    >>> round(scenario.device.true_fsr_hz / 1e9, 6)  # GHz: Table 1's delay spread
    49.584815
    >>> float(sweep["frequency_hz"][0]), sweep["p1_w"].shape
    (193375207592707.3, (5,))
    >>> cascade = Scenario(cascade_fsrs_hz=(5e12, 500e9, 50e9), samples=8, x_unit="nm")
    >>> list(cascade.tables()[0])[:4]
    ['wavelength_nm', 'p11_w', 'p12_w', 'p13_w']
    >>> thermal = Scenario(samples=4, platform="sin", ramp_k=(290.0, 300.0))
    >>> thermal.tables()[0]["temperature_k"].tolist()
    [290.0, 293.3333333333333, 296.6666666666667, 300.0]
    >>> laser = Scenario(laser=4, laser_rate_hz=1e6, white_fm_hz2_per_hz=1e8).laser_table()
    >>> list(laser)[:2], laser["time_s"].tolist()
    (['time_s', 'true_frequency_hz'], [0.0, 1e-06, 2e-06, 3e-06])
    >>> Scenario(ports=2)
    Traceback (most recent call last):
    ...
    wavemeter.exceptions.InputError: ports must be an integer from 3 to 64, got 2
    """

    ports: int = 3
    seed: int = 1
    samples: int = 2001
    span_fsr: float | None = None
    power_w: float = DEFAULT_POWER_W
    noise_w: float | None = None
    fsr_hz: float | None = None
    cascade_fsrs_hz: tuple[float, ...] | None = None
    band_hz: tuple[float, float] | None = None
    test: int = 0
    x_unit: str = "Hz"
    power_unit: str = "W"
    power_fluctuation: float = 0.0
    dark_offset_w: tuple[float, ...] | None = None
    port_noise_w: tuple[float, ...] | None = None
    dispersion_s2: float | None = None
    spectral: str | None = None
    coupler_slope_sigma_per_thz: float | None = None
    responsivity_slope_sigma_per_thz: float | None = None
    power_drift: float = 0.0
    thermal_drift_k: float | None = None
    platform: str | None = None
    temperature_k: float | None = None
    ramp_k: tuple[float, float] | None = None
    repeat: int = 1
    monitor: bool = True
    laser: int = 0
    laser_rate_hz: float | None = None
    laser_center_hz: float | None = None
    white_fm_hz2_per_hz: float = 0.0
    flicker_fm_hz2: float = 0.0
    random_walk_fm_hz2_per_s: float = 0.0
    laser_drift_hz_per_s: float = 0.0
    dark: int = 0
    sweep_axis: str | None = None
    reference_cell: str | None = None
    #: drawn when the scenario is made: the device, its spectral preset, the noise std (W)
    _device: Interferometer | CascadeInterferometer = field(init=False, repr=False, compare=False)
    _preset: SpectralPreset | None = field(init=False, repr=False, compare=False)
    _noise_std_w: float | np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        given = {
            item.name: getattr(self, item.name) for item in dataclasses.fields(self) if item.init
        }
        values = checks.normalised(given)
        values["sweep_axis"], values["reference_cell"] = check_cell(
            values["sweep_axis"], values["reference_cell"]
        )
        checks.check_related(values)
        for name, value in values.items():
            object.__setattr__(self, name, value)
        device, preset = self._cascade() if self.is_cascade else self._single_device()
        object.__setattr__(self, "_device", device)
        object.__setattr__(self, "_preset", preset)
        object.__setattr__(self, "_noise_std_w", self._detector_noise_w())
        ends_hz = self.sweep_hz()[[0, -1]]  # the spectral slopes are linear: check the ends
        for stage in device.stages if self.is_cascade else (device,):
            stage.true_map(frequency_hz=ends_hz)

    # ------------------------------------------------------------------ the device
    @property
    def is_cascade(self) -> bool:
        """Whether the device is a cascade (``cascade_fsrs_hz`` given)."""
        return self.cascade_fsrs_hz is not None

    @property
    def device(self) -> Interferometer | CascadeInterferometer:
        """The simulated device, faults, thermal and spectral behaviour included."""
        return self._device

    @property
    def spectral_preset(self) -> SpectralPreset | None:
        """What a single device's spectral slopes were drawn with; None when no slopes were
        drawn (no platform or slope given: only ``dispersion_s2`` applies)."""
        return self._preset

    def _single_device(self) -> tuple[Interferometer, SpectralPreset | None]:
        """Table 1, then the spectral behaviour, the dark offset and the thermal platform."""
        fsr_hz = DEFAULT_FSR_HZ if self.fsr_hz is None else self.fsr_hz
        device, preset = self._spectral(
            Interferometer.table1(self.ports, seed=self.seed, fsr_hz=fsr_hz)
        )
        offset_w = self.dark_offset_w
        if offset_w is not None:
            offset_w = checks.per_port("dark_offset_w", offset_w, device.ports, single=True)
        device = dataclasses.replace(device, dark_offset_w=offset_w)
        if self.platform is not None:
            device = device.with_thermal(self.platform)
        return device, preset

    def _spectral(self, device: Interferometer) -> tuple[Interferometer, SpectralPreset | None]:
        """The device with the platform's dispersion and slopes, each replaced by its field
        when given; with ``dispersion_s2`` alone (or nothing) no slopes are drawn."""
        given = {
            preset_field: getattr(self, name)
            for name, preset_field in _SPECTRAL_FIELDS.items()
            if getattr(self, name) is not None
        }
        if self.spectral is None and set(given) <= {"dispersion_s2"}:
            return dataclasses.replace(device, dispersion_s2=given.get("dispersion_s2", 0.0)), None
        preset = SpectralPreset(0.0, 0.0, 0.0, 0.0)
        if self.spectral is not None:
            preset = SPECTRAL_PRESETS[self.spectral]
        preset = dataclasses.replace(preset, **given)
        rng = np.random.default_rng([self.seed, SPECTRAL_STREAM])
        return device.with_spectral(preset, seed=rng), preset

    def _cascade(self) -> tuple[CascadeInterferometer, None]:
        """The cascade centred in its band; refuses a band its coarsest stage does not
        exceed."""
        low, high = self._band_hz
        device = CascadeInterferometer.table1(
            self.cascade_fsrs_hz,
            ports=self.ports,
            seed=self.seed,
            center_hz=(low + high) / 2,
            spectral=self.spectral,
        )
        checks.check_band_covered(device, self.cascade_fsrs_hz, (low, high))
        return device, None

    @property
    def _band_hz(self) -> tuple[float, float]:
        return DEFAULT_CASCADE_BAND_HZ if self.band_hz is None else self.band_hz

    def _detector_noise_w(self):
        """Detector noise std (W): ``noise_w`` for every port, or ``port_noise_w`` per port."""
        if self.port_noise_w is None:
            return DEFAULT_NOISE_W if self.noise_w is None else self.noise_w
        return checks.per_port("port_noise_w", self.port_noise_w, self._device.ports, single=False)

    # ------------------------------------------------------------------ recordings
    def sweep_hz(self) -> np.ndarray:
        """Frequencies (Hz) of one calibration sweep, shape (samples,): evenly over
        ``span_fsr`` true FSRs about a single device's centre, the last a step short of
        the span (:meth:`Interferometer.sweep_hz`); or a cascade's band, ends included."""
        if self.is_cascade:
            return np.linspace(*self._band_hz, self.samples)
        span = DEFAULT_SPAN_FSR if self.span_fsr is None else self.span_fsr
        return self._device.sweep_hz(self.samples, span)

    def _noise_rng(self) -> np.random.Generator:
        """The seed's (as the demo) at the reference temperature, else a stream of the
        seed and the temperatures given (mK)."""
        given = self.ramp_k or (self.temperature_k,)
        if given == (None,):
            return np.random.default_rng(self.seed)
        millikelvin = [round(value * 1e3) for value in given]
        return np.random.default_rng([self.seed, TEMPERATURE_STREAM, *millikelvin])

    def _temperature_k(self, rows: int) -> np.ndarray | None:
        """Chip temperature (K) of a recording of ``rows`` in time order: constant, or the
        ramp over it; None without a thermal platform."""
        if self.platform is None:
            return None
        if self.ramp_k is not None:
            return np.linspace(*self.ramp_k, rows)
        temperature = self.temperature_k
        if temperature is None:
            temperature = self._device.reference_temperature_k
        return np.full(rows, temperature)

    def _sweep_drift(self, rows: int) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The sweep's source-power factor and bias drift (rad), None when off."""
        power_factor = bias_drift_rad = None
        if self.power_drift > 0:
            drift_rng = np.random.default_rng([self.seed, DRIFT_STREAM])
            power_factor = slow_power_drift(rows, self.power_drift, drift_rng)
        if self.thermal_drift_k:
            rad_per_k = self._device.thermal_phase_rad_per_k or DEFAULT_THERMAL_RAD_PER_K
            bias_drift_rad = thermal_ramp_rad(rows, self.thermal_drift_k, rad_per_k)
        return power_factor, bias_drift_rad

    def _readings(self, frequency_hz, rng, name, progress, **drifts) -> dict[str, np.ndarray]:
        varies = self.power_fluctuation > 0 or self.power_drift > 0
        return readings(
            self._device,
            frequency_hz,
            rng,
            power_w=self.power_w,
            noise_w=self._noise_std_w,
            power_fluctuation=self.power_fluctuation,
            power_unit=self.power_unit,
            monitor=varies and self.monitor,
            progress=progress(name, frequency_hz.size, unit="rows") if progress else None,
            **drifts,
        )

    def tables(self, progress=None) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray] | None]:
        """The calibration sweep and the test readings, as ``wavemeter simulate`` writes them.

        Parameters
        ----------
        progress : callable, optional
            ``progress(table, total, unit="rows")`` returning a context manager that yields
            ``advance(rows)`` (as :func:`wavemeter.progress.progress_bar`); ``table`` is
            ``"sweep"`` or ``"test"``.

        Returns
        -------
        sweep : dict of str to ndarray, each shape (samples * repeat,)
            Column name -> values in file order: the axis, the ports, the monitor when the
            source power varies, ``temperature_k`` on a thermal platform.
        test : dict of str to ndarray, each shape (test,), or None
            The same at frequencies uniform over the sweep, the axis as ``true_<axis>``;
            None when ``test`` is 0.
        """
        rng = self._noise_rng()
        sweep_hz = np.tile(self.sweep_hz(), self.repeat)
        test_hz = rng.uniform(sweep_hz.min(), sweep_hz.max(), self.test) if self.test else None
        sweep_k, test_k = self._temperature_k(sweep_hz.size), self._temperature_k(self.test)
        if self.platform is not None and self.ramp_k is not None:
            test_k = rng.uniform(min(self.ramp_k), max(self.ramp_k), self.test)
        power_factor, bias_drift_rad = self._sweep_drift(sweep_hz.size)
        absolute = {}
        if self.sweep_axis is not None or self.reference_cell is not None:
            swept = cell_sweep(self.sweep_hz(), self.seed, self.sweep_axis, self.reference_cell)
            sweep_hz = np.tile(swept.true_hz, self.repeat)
            recorded_hz = np.tile(swept.recorded_hz, self.repeat)
            absolute[TRUE_COLUMN] = sweep_hz
            if swept.transmission is not None:
                absolute[CELL_COLUMN] = np.tile(swept.transmission, self.repeat)
        sweep = {
            axis_column(self.x_unit): hz_to_axis(
                recorded_hz if absolute else sweep_hz, self.x_unit
            ),
            **absolute,
            **self._readings(
                sweep_hz,
                rng,
                "sweep",
                progress,
                power_factor=power_factor,
                bias_drift_rad=bias_drift_rad,
                temperature_k=sweep_k,
            ),
        }
        if not self.test:
            return sweep, None
        test = {
            axis_column(self.x_unit, "true_"): hz_to_axis(test_hz, self.x_unit),
            **self._readings(test_hz, rng, "test", progress, temperature_k=test_k),
        }
        return sweep, test

    def laser_table(self, progress=None) -> dict[str, np.ndarray] | None:
        """The laser record: readings of a laser with power-law frequency noise and drift.

        Reading ``k`` is the laser's mean frequency over ``[k, k + 1] / laser_rate_hz``
        (:func:`~wavemeter.simulation.laser_frequency_hz`), read like a test reading (the
        device's faults, no sweep drift). ``wavemeter noise`` reads it with the
        calibration of the sweep (``--time-column time_s`` or ``--rate``).

        Parameters
        ----------
        progress : callable, optional
            As :meth:`tables` takes it; ``table`` is ``"laser"``.

        Returns
        -------
        dict of str to ndarray, each shape (laser,), or None
            ``time_s`` (``k / laser_rate_hz``, s), the true frequency as ``true_<axis>``,
            then the columns of a test reading; None when ``laser`` is 0.
        """
        if not self.laser:
            return None
        rate_hz = DEFAULT_LASER_RATE_HZ if self.laser_rate_hz is None else self.laser_rate_hz
        center_hz = self._device.center_hz if self.laser_center_hz is None else self.laser_center_hz
        frequency_rng, reading_rng = np.random.default_rng([self.seed, LASER_STREAM]).spawn(2)
        frequency_hz = laser_frequency_hz(
            self.laser,
            rate_hz,
            center_hz=center_hz,
            white_fm_hz2_per_hz=self.white_fm_hz2_per_hz,
            flicker_fm_hz2=self.flicker_fm_hz2,
            random_walk_fm_hz2_per_s=self.random_walk_fm_hz2_per_s,
            drift_hz_per_s=self.laser_drift_hz_per_s,
            rng=frequency_rng,
        )
        return {
            "time_s": np.arange(self.laser) / rate_hz,
            axis_column(self.x_unit, "true_"): hz_to_axis(frequency_hz, self.x_unit),
            **self._readings(
                frequency_hz,
                reading_rng,
                "laser",
                progress,
                temperature_k=self._temperature_k(self.laser),
            ),
        }

    def dark_table(self, progress=None) -> dict[str, np.ndarray] | None:
        """Dark readings: the device read with the source off, as ``calibrate --dark`` takes them.

        Parameters
        ----------
        progress : callable, optional
            As :meth:`tables` takes it; ``table`` is ``"dark"``.

        Returns
        -------
        dict of str to ndarray, each shape (dark,), or None
            The port columns (dark offset plus detector noise), the monitor when the source
            power varies and ``temperature_k`` on a thermal platform, as the sweep has them;
            None when ``dark`` is 0.
        """
        if not self.dark:
            return None
        frequency_hz = np.full(self.dark, float(np.mean(self.sweep_hz())))
        return self._readings(
            frequency_hz,
            np.random.default_rng([self.seed, DARK_STREAM]),
            "dark",
            progress,
            power_factor=np.zeros(self.dark),
            temperature_k=self._temperature_k(self.dark),
        )

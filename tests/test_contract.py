"""One contract every calibrator keeps (scikit-rf calibration-mixin style).

:class:`CalibratorContract` holds the checks; each ``Test*`` subclass names a calibrator and
the devices on which its model is exact and its estimator efficient:

- recovery without noise on a device where the method's model holds exactly: the error is
  float64 rounding, bounded by ``NOISELESS_HZ``;
- noise-limited recovery with Table 1 noise on a device where the estimator is efficient:
  the rms error lies within the statistics of the Cramer-Rao bound of the information the
  method uses (all ports with the source power unknown; or, for methods that assume the
  calibration power, the ports they read with the power known).

The conventional method and Kleijn's fit are not exact on impaired devices (an ideal map;
the sum of port powers as source power), so their recovery clauses use an ideal device.

Enrolment is automatic: a test class is made for every class in the calibration registry
(every calibrator with a file tag), with the per-class settings of ``CASES`` where the
defaults do not fit; a new calibrator cannot skip the contract. Each call passes the
per-reading inputs the class declares in ``requires`` (the truth as ``coarse_hz``; the
chip temperature as ``temperature_k``). A class that requires the temperature is fitted
on a device whose fringes move with it (the silicon-nitride preset), swept at four
temperatures about the simulator's reference temperature, and tested at that one.
"""

from __future__ import annotations

import functools
import math
from copy import deepcopy

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.contract.base import BaseCalibrator
from wavemeter.calibration.files.registry import registered

from .helpers import bound_rms_hz, thermal_sweep, with_bad_readings

POWER_W = 1e-3
NOISE_W = 5e-7  # Table 1: 5e-4 mW at 1 mW
SWEEP_SAMPLES = 1000
TEST_SAMPLES = 10_000
#: 30 ulp of a 193 THz frequency in float64 (ulp = 2**-5 Hz): rounding, nothing more
NOISELESS_HZ = 1.0
#: relative standard error of an rms over TEST_SAMPLES Gaussian errors is 1/sqrt(2 M)
RMS_STATISTICS = 4.0 / math.sqrt(2 * TEST_SAMPLES)
#: fitted values per port-count bound the calibration excess: sqrt(1 + k / N), k <= 3 n + 1
CALIBRATION_EXCESS = math.sqrt(1.0 + 13 / SWEEP_SAMPLES)


#: fitted calibrators by (contract, device kind, noise), for :meth:`CalibratorContract.fitted`
FITTED = {}


def make_device(kind: str, ports: int, thermal: bool = False) -> wm.Interferometer:
    device = (
        wm.Interferometer.ideal(ports)
        if kind == "ideal"
        else wm.Interferometer.table1(ports, seed=7)
    )
    return device.with_thermal("sin") if thermal else device


@functools.cache
def simulated(kind: str, ports: int, noise_w: float, thermal: bool = False):
    """Sweep (powers, frequencies, per-reading fit inputs) and test (powers, frequencies)
    of one device; with ``thermal`` the sweep is taken at four temperatures and the test
    readings at the device's reference temperature."""
    device = make_device(kind, ports, thermal)
    sweep_hz = device.sweep_hz(SWEEP_SAMPLES)
    # inside the calibrated span: a calibration set refuses readings beyond it
    test_hz = np.random.default_rng(13).uniform(sweep_hz[0], sweep_hz[-1], TEST_SAMPLES)
    if thermal:
        sweep, sweep_hz, temperature = thermal_sweep(device, SWEEP_SAMPLES, noise_w, rng=11)
        inputs = {"temperature_k": temperature}
    else:
        sweep, inputs = device.powers(sweep_hz, POWER_W, noise_w, rng=11), {}
    test = device.powers(test_hz, POWER_W, noise_w, rng=12)
    for array in (sweep_hz, test_hz, sweep, test, *inputs.values()):
        array.setflags(write=False)
    return device, sweep, sweep_hz, test, test_hz, inputs


def reading_inputs(calibrator, frequency_hz) -> dict:
    """The per-reading inputs a calibrator declares it needs: the true frequencies, and
    the temperature of the test readings (the device's reference temperature)."""
    inputs = {}
    if "coarse_hz" in calibrator.requires:
        inputs["coarse_hz"] = frequency_hz
    if "temperature_k" in calibrator.requires:
        inputs["temperature_k"] = wm.Interferometer.reference_temperature_k
    return inputs


def rows_of(inputs: dict, rows) -> dict:
    """The per-reading fit inputs of some sweep readings."""
    return {name: values[rows] for name, values in inputs.items()}


def rms(values) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


class CalibratorContract:
    """Checks shared by every calibrator; subclasses set the class attributes."""

    #: factory of an unfitted calibrator
    make = None
    ports = 3
    #: device on which the method's model holds exactly (noiseless recovery)
    exact_device = "table1"
    #: device on which the method's estimator is efficient (noise-limited recovery)
    efficient_device = "ideal"
    #: ports the method reads; None for all
    used_ports = None
    #: the method assumes the calibration source power (offsets or a fixed ellipse)
    known_power = False
    #: predictions lie within half an FSR of the centre (False: anywhere in the band)
    wraps_to_one_fsr = True

    def data(self, kind: str, noise_w: float):
        """:func:`simulated` for this class (thermal when it requires the temperature)."""
        thermal = "temperature_k" in self.make().requires
        return simulated(kind, self.ports, noise_w, thermal)

    def fitted(self, kind: str, noise_w: float):
        """The calibrator fitted on :meth:`data`, with the device and the test readings: one
        fit per contract, device and noise, each check given its own copy."""
        key = (type(self), kind, noise_w)
        if key not in FITTED:
            device, sweep, sweep_hz, test, test_hz, inputs = self.data(kind, noise_w)
            FITTED[key] = self.make().fit(sweep, sweep_hz, **inputs), device, test, test_hz
        cal, device, test, test_hz = FITTED[key]
        return deepcopy(cal), device, test, test_hz

    def error_hz(self, predicted_hz, truth_hz, fsr_hz):
        """Frequency error (Hz): modulo the FSR for a method that reads within one FSR,
        absolute for one that reads across a band."""
        if self.wraps_to_one_fsr:
            return wm.frequency_error_hz(predicted_hz, truth_hz, fsr_hz)
        return predicted_hz - truth_hz

    def bound_rms(self, device, test_hz) -> float:
        """RMS of the Cramer-Rao bound (Hz) of the information the method uses."""
        used = range(self.ports) if self.used_ports is None else self.used_ports
        return bound_rms_hz(device, test_hz, used, self.known_power)

    def estimator_excess(self, device, test_hz) -> float:
        """Ratio of the estimator's first-order noise to the bound (1: efficient)."""
        return 1.0

    # ------------------------------------------------------------------ recovery
    def test_recovers_exact_device_without_noise(self):
        cal, device, test, test_hz = self.fitted(self.exact_device, 0.0)
        predicted = cal.predict(test, **reading_inputs(cal, test_hz))
        error = self.error_hz(predicted, test_hz, device.true_fsr_hz)
        assert np.max(np.abs(error)) <= NOISELESS_HZ
        assert abs(cal.fsr_hz_ / device.true_fsr_hz - 1) < 1e-12

    def test_noise_limited_on_efficient_device(self):
        cal, device, test, test_hz = self.fitted(self.efficient_device, NOISE_W)
        predicted = cal.predict(test, **reading_inputs(cal, test_hz))
        error = self.error_hz(predicted, test_hz, device.true_fsr_hz)
        bound = self.bound_rms(device, test_hz)
        excess = self.estimator_excess(device, test_hz)
        assert rms(error) <= bound * excess * CALIBRATION_EXCESS * (1 + RMS_STATISTICS)
        assert rms(error) >= bound * (1 - RMS_STATISTICS)  # nothing beats the bound

    # ------------------------------------------------------------------ estimator shape
    def test_fit_returns_self_and_prediction_shape(self):
        device, sweep, sweep_hz, test, test_hz, inputs = self.data("table1", NOISE_W)
        cal = self.make()
        assert cal.fit(sweep, sweep_hz, **inputs) is cal
        first = reading_inputs(cal, test_hz[:7])
        predicted = cal.predict(test[:7], **first)
        assert predicted.shape == (7,)
        if self.wraps_to_one_fsr:
            assert np.all(np.abs(predicted - cal.center_hz_) <= cal.fsr_hz_ / 2)
        else:
            low, high = cal.span_hz_
            assert np.all(
                (predicted >= low - cal.fsr_hz_ / 2) & (predicted <= high + cal.fsr_hz_ / 2)
            )
        assert cal.predict(test[0], **reading_inputs(cal, test_hz[0])).shape == (1,)
        assert cal.phase(test[:7], **first).shape == (7,)

    def test_inputs_not_modified(self):
        _, sweep, sweep_hz, test, test_hz, inputs = self.data("table1", NOISE_W)
        writable = [np.array(a) for a in (sweep, sweep_hz, test, test_hz, *inputs.values())]
        copies = [a.copy() for a in writable]
        fit_inputs = dict(zip(inputs, writable[4:], strict=True))
        cal = self.make().fit(writable[0], writable[1], **fit_inputs)
        cal.predict(writable[2], **reading_inputs(cal, writable[3]))
        cal.phase(writable[2], **reading_inputs(cal, writable[3]))
        for array, copy in zip(writable, copies, strict=True):
            assert array.tobytes() == copy.tobytes()

    def test_save_load_round_trip_is_bit_exact(self, tmp_path):
        cal, _, test, test_hz = self.fitted("table1", NOISE_W)
        path = tmp_path / "cal.wmcal.json"
        cal.save(path)
        loaded = wm.load_calibration(path)
        assert type(loaded) is type(cal)
        assert loaded.get_params_for_file() == cal.get_params_for_file()
        inputs = reading_inputs(cal, test_hz)
        assert loaded.predict(test, **inputs).tobytes() == cal.predict(test, **inputs).tobytes()
        assert loaded.phase(test, **inputs).tobytes() == cal.phase(test, **inputs).tobytes()
        assert loaded.fsr_hz_ == cal.fsr_hz_
        assert loaded.center_hz_ == cal.center_hz_

    def test_predict_before_fit_raises(self):
        _, _, _, test, test_hz, _ = self.data("table1", NOISE_W)
        inputs = reading_inputs(self.make(), test_hz)
        with pytest.raises(wm.NotFittedError, match="not fitted"):
            self.make().predict(test, **inputs)
        with pytest.raises(wm.NotFittedError, match="not fitted"):
            self.make().phase(test, **inputs)

    def test_rejects_nan_rows(self):
        _, sweep, sweep_hz, _, _, inputs = self.data("table1", NOISE_W)
        bad = np.array(sweep)
        bad[5, 1] = np.nan
        with pytest.raises(wm.InputError, match=r"NaN or inf in rows \[5\]"):
            self.make().fit(bad, sweep_hz, **inputs)

    def test_rejects_wrong_port_count(self):
        cal, _, test, test_hz = self.fitted("table1", NOISE_W)
        with pytest.raises(wm.InputError, match=f"but the calibration has {self.ports}"):
            cal.predict(np.column_stack([test, test[:, :1]]), **reading_inputs(cal, test_hz))

    def test_rejects_fewer_than_four_samples(self):
        _, sweep, sweep_hz, _, _, inputs = self.data("table1", NOISE_W)
        rows = slice(0, 900, 300)
        with pytest.raises(wm.InputError, match="at least 4 samples, got 3"):
            self.make().fit(sweep[rows], sweep_hz[rows], **rows_of(inputs, rows))

    def test_learned_attributes_end_in_underscore(self):
        cal = self.make()
        settings = set(cal.get_params())
        assert set(vars(cal)) == settings  # __init__ stores settings only
        _, sweep, sweep_hz, _, _, inputs = self.data("table1", NOISE_W)
        cal.fit(sweep, sweep_hz, **inputs)
        learned = set(vars(cal)) - settings
        assert learned >= set(wm.Calibrator.common_attributes)
        assert all(name.endswith("_") and not name.startswith("_") for name in learned)

    def test_get_params_round_trip(self):
        cal = self.make()
        clone = type(cal)(**cal.get_params())
        assert clone.get_params() == cal.get_params()
        assert repr(clone) == repr(cal)

    # ------------------------------------------------------------------ one prediction API
    def test_declared_inputs_are_required_by_name(self):
        cal, _, test, _ = self.fitted("table1", NOISE_W)
        for name in sorted(cal.requires):
            with pytest.raises(wm.InputError, match=f"needs {name}"):
                cal.predict(test[:3])
            with pytest.raises(wm.InputError, match=f"needs {name}"):
                cal.phase(test[:3])

    def test_frequency_std_is_offered_exactly_where_declared(self):
        cal, _, test, test_hz = self.fitted("table1", NOISE_W)
        inputs = reading_inputs(cal, test_hz[:5])
        if "frequency_std" in cal.capabilities:
            std = cal.frequency_std_hz(test[:5], **inputs)
            assert std.shape == (5,) and np.all(np.isfinite(std) & (std > 0))
        else:
            with pytest.raises(wm.InputError, match="no per-reading uncertainty"):
                cal.frequency_std_hz(test[:5], **inputs)

    def test_flags_mark_only_the_bad_readings(self):
        """Clean readings carry no flag; NaN, dark and tenfold-power readings are marked."""
        cal, _, test, test_hz = self.fitted("table1", NOISE_W)
        inputs = reading_inputs(cal, test_hz[:200])
        readings = test[:200].copy()
        flags = cal.flags(readings, **inputs)
        assert flags.shape == (200,) and flags.dtype == np.int64
        # OFF_MODEL at p < 1e-6 and 200 readings in the calibrated span and power
        assert np.count_nonzero(flags) == 0
        readings[0], readings[1], readings[2] = np.nan, 0.0, 10.0 * readings[2]
        marked = cal.flags(readings, **inputs)
        assert marked[0] == wm.ReadingFlag.INVALID and marked[1] & wm.ReadingFlag.INVALID
        assert marked[2] & wm.ReadingFlag.POWER_RANGE
        np.testing.assert_array_equal(marked[3:], flags[3:])

    def test_readout_agrees_with_predict_and_isolates_bad_readings(self):
        """``readout`` gives predict's, frequency_std_hz's and flags' numbers at once; a NaN
        or dark reading gets NaN values and INVALID without costing the others."""
        cal, _, test, test_hz = self.fitted("table1", NOISE_W)
        inputs = reading_inputs(cal, test_hz[:50])
        readings = test[:50].copy()
        readings[3], readings[7] = np.nan, 0.0
        found = cal.readout(readings, **inputs)
        good = np.ones(50, dtype=bool)
        good[[3, 7]] = False
        assert set(found.extras) == set(cal.reading_outputs)
        assert np.isnan(found.frequency_hz[~good]).all()
        assert (found.flags[~good] & wm.ReadingFlag.INVALID).all()
        kept = {name: value[good] if np.ndim(value) else value for name, value in inputs.items()}
        np.testing.assert_allclose(
            found.frequency_hz[good], cal.predict(readings[good], **kept), rtol=0, atol=1e-3
        )
        np.testing.assert_array_equal(found.flags, cal.flags(readings, **inputs))
        if "frequency_std" in cal.capabilities:
            np.testing.assert_allclose(
                found.frequency_std_hz[good],
                cal.frequency_std_hz(readings[good], **kept),
                rtol=1e-9,
            )
        else:
            assert np.isnan(found.frequency_std_hz).all()
        for values in found.extras.values():
            assert values.shape == (50,) and np.isnan(values[~good]).all()

    def test_row_reader_agrees_with_readout_on_good_and_bad_readings(self):
        """What stream and the service read with gives each reading readout's numbers (to
        float64 rounding; measured <= 1e-15), flags and extras; a missing input is named."""
        cal, _, test, test_hz = self.fitted("table1", NOISE_W)
        rng = np.random.default_rng(29)
        picked = rng.choice(len(test), size=120, replace=False)
        rows, inputs = with_bad_readings(test[picked], reading_inputs(cal, test_hz[picked]), rng)
        batch, read = cal.readout(rows, **inputs), cal.row_reader()
        found = [read(row, **{k: v[i] for k, v in inputs.items()}) for i, row in enumerate(rows)]
        np.testing.assert_array_equal([r.flags for r in found], batch.flags)
        expected = {"frequency_hz": batch.frequency_hz, "frequency_std_hz": batch.frequency_std_hz}
        for name, values in {**expected, **batch.extras}.items():
            got = [r.extras[name] if name in batch.extras else getattr(r, name) for r in found]
            np.testing.assert_allclose(got, values, rtol=1e-12, atol=0, err_msg=name)
        assert (batch.flags[[0, 1, 2, 6]] & wm.ReadingFlag.INVALID).all()
        assert batch.flags[4] & wm.ReadingFlag.POWER_RANGE
        for name in cal.requires:
            with pytest.raises(wm.InputError, match=name):
                read(rows[10])

    def test_score_is_minus_the_rms_error(self):
        cal, device, test, test_hz = self.fitted("table1", NOISE_W)
        inputs = reading_inputs(cal, test_hz)
        error = self.error_hz(cal.predict(test, **inputs), test_hz, cal.fsr_hz_)
        assert cal.score(test, test_hz, **inputs) == pytest.approx(-rms(error), rel=1e-12)

    def test_set_params_changes_a_setting_and_names_unknown_ones(self):
        cal = self.make()
        name, value = next(iter(cal.get_params().items()))
        assert cal.set_params(**{name: value}) is cal
        with pytest.raises(wm.InputError, match="'no_such_setting' is not a setting"):
            cal.set_params(no_such_setting=1)


def pinv_excess(self, device, test_hz):
    """The pseudo-inverse ignores the cone: first-order noise ``|A+^T u_t| sigma / P``."""
    phase = 2 * np.pi * (test_hz - device.center_hz) * device.delay_s
    matrix = device.true_map()
    tangent = np.stack([-np.sin(phase), np.cos(phase), np.zeros_like(phase)], axis=-1)
    pinv_std = np.linalg.norm(tangent @ np.linalg.pinv(matrix), axis=1) * NOISE_W / POWER_W
    first_order = rms(pinv_std) * device.true_fsr_hz / (2 * np.pi)
    return first_order / bound_rms_hz(device, test_hz, range(self.ports), False)


#: a two-stage cascade for the contract: a coarse stage whose FSR exceeds the 800 GHz band
#: and a fine one of 8 FSRs across it; equal power shares
CASCADE_FSRS_HZ = (1e12, 100e9)
CASCADE_BAND_HZ = 0.8e12


@functools.cache
def simulated_cascade(kind: str, noise_w: float):
    """:func:`simulated` for a cascade over ``CASCADE_BAND_HZ``: its finest stage stands for
    the device (the FSR and the bound are that stage's)."""
    if kind == "ideal":
        stages = tuple(wm.Interferometer.ideal(3, fsr_hz=fsr) for fsr in CASCADE_FSRS_HZ)
        device = wm.CascadeInterferometer(stages)
    else:
        device = wm.CascadeInterferometer.table1(CASCADE_FSRS_HZ, ports=3, seed=7, spectral=None)
    step = CASCADE_BAND_HZ / SWEEP_SAMPLES
    sweep_hz = device.center_hz - CASCADE_BAND_HZ / 2 + step * np.arange(SWEEP_SAMPLES)
    test_hz = np.random.default_rng(13).uniform(sweep_hz[0], sweep_hz[-1], TEST_SAMPLES)
    sweep = device.powers(sweep_hz, POWER_W, noise_w, rng=11)
    test = device.powers(test_hz, POWER_W, noise_w, rng=12)
    for array in (sweep_hz, test_hz, sweep, test):
        array.setflags(write=False)
    return device.stages[-1], sweep, sweep_hz, test, test_hz, {}


def cascade_bound(self, device, test_hz):
    """The finest stage's bound at its share of the source power (the bound scales as
    ``1 / power``)."""
    return bound_rms_hz(device, test_hz, range(3), False) * len(CASCADE_FSRS_HZ)


#: per file tag: (case name, settings that differ from CalibratorContract's); a registered
#: class missing here runs the contract with the defaults
CASES = {
    "learned": [
        # the paper's claim: noise-limited on an impaired device
        ("", {"efficient_device": "table1", "estimator_excess": pinv_excess}),
        # the cone-constrained ML phase attains the bound itself
        (
            "ConeML",
            {
                "make": staticmethod(functools.partial(wm.Calibrator, retrieval="ml")),
                "efficient_device": "table1",
            },
        ),
    ],
    # the ideal map is the model; on Table 1 it is off by ~0.5 GHz
    "conventional": [("", {"exact_device": "ideal"})],
    # the offsets are absolute powers
    "extended_conventional": [("", {"known_power": True})],
    # the learned map's contract at the reference temperature, with the pseudo-inverse
    "thermal": [("", {"efficient_device": "table1", "estimator_excess": pinv_excess})],
    # a one-FSR sweep: the paper's orders (1, 0), the learned map's contract via coarse_hz
    "wideband": [("", {"efficient_device": "table1", "estimator_excess": pinv_excess})],
    # absolute frequency across a band from two stages; the finest stage's bound
    "cascade": [
        (
            "",
            {
                "make": staticmethod(
                    functools.partial(wm.CascadeCalibrator, fsr_hz=CASCADE_FSRS_HZ)
                ),
                "ports": 2 * 3,
                "wraps_to_one_fsr": False,
                "data": lambda self, kind, noise_w: simulated_cascade(kind, noise_w),
                "bound_rms": cascade_bound,
            },
        )
    ],
    # the sum of port powers is the source power only when ideal
    "nonlinear_fit": [("", {"exact_device": "ideal"})],
    # in quadrature on a 90-degree hybrid: a circle, Heydemann efficient; a fixed ellipse
    # assumes the calibration power
    "ellipse": [("", {"ports": 4, "used_ports": (0, 1), "known_power": True})],
    # one window over the one-FSR sweep: the learned map's contract, reached via coarse_hz
    "calibration_set": [
        ("", {"efficient_device": "table1", "estimator_excess": pinv_excess}),
        (
            "ConventionalWindows",
            {
                "make": staticmethod(
                    functools.partial(wm.CalibrationSet, window=wm.ConventionalCalibrator())
                ),
                "exact_device": "ideal",
            },
        ),
    ],
}


def package_calibrators() -> dict[str, type]:
    """Registered calibrators of this package (benchmarks register adapters of their own)."""
    return {
        tag: cls for tag, cls in registered().items() if cls.__module__.startswith("wavemeter.")
    }


def _enrol() -> list[str]:
    """A contract test class per registered calibrator (and case), put in this module."""
    names = []
    for tag, cls in package_calibrators().items():
        for suffix, settings in CASES.get(tag, [("", {})]):
            name = f"Test{cls.__name__}{suffix}"
            globals()[name] = type(name, (CalibratorContract,), {"make": cls, **settings})
            names.append(name)
    return names


ENROLLED = _enrol()


def test_every_calibrator_class_is_registered_and_enrolled():
    """Every concrete class with a file tag is in the registry, and so in the contract."""
    found, stack = set(), [BaseCalibrator]
    while stack:
        cls = stack.pop()
        stack.extend(cls.__subclasses__())
        if cls.__dict__.get("method") and cls.__module__.startswith("wavemeter."):
            found.add(cls)
    ours = package_calibrators()
    assert found == set(ours.values())
    assert set(CASES) <= set(ours)  # no settings for a tag that no longer exists
    assert len(ENROLLED) == sum(len(CASES.get(tag, [None])) for tag in ours)


def test_a_second_class_with_a_taken_tag_is_refused():
    with pytest.raises(wm.WavemeterError, match="'learned' .* is already used by"):
        type("Impostor", (BaseCalibrator,), {"method": "learned"})

"""The right cause on the sweeps users make (issue 29): wide sweeps of a device that changes
with the wavelength, rounded frequency axes, and clean sweeps of every method.

Each case is simulated as ``wavemeter simulate`` writes it (``Scenario``) and calibrated as
a user would; one seed per fault (the many-seed rates are in ``benchmarks/trust.py``, the
second table of ``make trust``). The controls check that the naming follows the evidence:
a drift in time on the same wide sweep keeps its own cause, and a stepped laser whose
repeated readings share their exact frequency raises nothing.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.checks.misfit_causes import CAUSES, REMEDIES
from wavemeter.cli.app import warning_text
from wavemeter.simulation import Scenario
from wavemeter.units import FREQUENCY_UNITS, SPEED_OF_LIGHT_M_S

from .helpers import NOISE_W, POWER_W

WIDE = {"span_fsr": 24.0, "samples": 4800}
RESIDUAL_CAUSES = {"power_drift", "phase_drift", "dispersion", "other_misfit", "quantised_axis"}


def ports(table: dict) -> np.ndarray:
    return np.column_stack([values for name, values in table.items() if name.startswith("p")])


def fitted(calibrator, powers, frequency, **inputs):
    """The fitted calibrator and the warnings it gave."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", wm.CalibrationWarning)
        calibrator.fit(powers, frequency, **inputs)
    return calibrator, [w.message for w in caught if isinstance(w.message, wm.CalibrationWarning)]


def scenario_fit(calibrator, seed: int = 2, **fields):
    sweep, _ = Scenario(seed=seed, **fields).tables()
    inputs = {"temperature_k": sweep["temperature_k"]} if "temperature_k" in sweep else {}
    axis = next(name for name in sweep if name.startswith("frequency"))
    return fitted(calibrator, ports(sweep), sweep[axis], **inputs)


def rounded_fit(unit: str, decimals: int, seed: int = 1):
    sweep, _ = Scenario(seed=seed, x_unit=unit).tables()
    axis = next(name for name in sweep if name.startswith(("frequency", "wavelength")))
    recorded = np.round(sweep[axis], decimals)
    if unit == "nm":
        frequency = SPEED_OF_LIGHT_M_S / (recorded * 1e-9)
    else:
        frequency = recorded * 10.0 ** FREQUENCY_UNITS[unit]
    return fitted(wm.Calibrator(), ports(sweep), frequency), recorded


def only_cause(notes) -> wm.CalibrationWarning:
    """The one warning of a residual cause (others, such as the map's checks, may join)."""
    named = [note for note in notes if note.cause in RESIDUAL_CAUSES]
    assert len(named) == 1, [(note.cause, str(note)) for note in notes]
    return named[0]


# ---------------------------------------------------------------------- wide sweeps
@pytest.mark.slow
@pytest.mark.parametrize(
    ("fields", "phase_too"),
    [({"spectral": "sin", "dispersion_s2": 1e-26}, True), ({"spectral": "sin"}, False)],
    ids=["slopes-and-dispersion", "slopes"],
)
def test_a_plain_calibration_over_a_wavelength_dependent_device_warns_dispersion(fields, phase_too):
    """24 FSRs of a SiN device (coupler and detector slopes, with 25x the platform's
    dispersion or its own): ``dispersion`` with the wide-band remedy, the ports' own changes
    as its evidence; no ``phase_drift`` or ``power_drift`` (issue 29 saw them)."""
    _, notes = scenario_fit(wm.Calibrator(), **fields, **WIDE)
    note = only_cause(notes)
    assert note.cause == "dispersion"
    assert note.remedy == REMEDIES["dispersion"] and "WidebandCalibrator" in note.remedy
    text = str(note)
    assert "each in its own way" in text and "no drift in time does" in text
    if phase_too:  # 25x the platform's dispersion: its even phase is named too
        assert "even in f - f0" in text
    assert "--" not in text  # library messages name parameters, never options
    assert warning_text(note).endswith("(options: --method wideband (or --per-fsr))")


@pytest.mark.slow
def test_dispersion_alone_over_a_wide_sweep_is_named_by_its_even_phase():
    _, notes = scenario_fit(wm.Calibrator(), dispersion_s2=1e-26, **WIDE)
    note = only_cause(notes)
    assert note.cause == "dispersion"
    assert "even in f - f0" in str(note) and "each in its own way" not in str(note)


def test_a_cycling_thermostat_over_a_wide_sweep_stays_phase_drift():
    """The control: three thermostat cycles over 24 FSRs are structure in time that no
    polynomial in frequency explains."""
    device = dataclasses.replace(wm.Interferometer.table1(3, seed=2), thermal_phase_rad_per_k=1.0)
    samples = WIDE["samples"]
    cycle = 0.025 * np.sin(2.0 * np.pi * 3.0 * np.arange(samples) / samples)
    frequency = device.sweep_hz(samples, WIDE["span_fsr"])
    powers = device.powers(
        frequency, POWER_W, NOISE_W, rng=3, temperature_k=device.reference_temperature_k + cycle
    )
    _, notes = fitted(wm.Calibrator(), powers, frequency)
    assert only_cause(notes).cause == "phase_drift"


def test_a_power_drift_over_a_wide_sweep_stays_power_drift_and_names_the_look_alike():
    """The control: a source-power drift moves every port alike; over many FSRs a slope of
    the detectors' responsivity common to them would too, and the message says so."""
    _, notes = scenario_fit(wm.Calibrator(), power_drift=0.05, monitor=False, **WIDE)
    note = only_cause(notes)
    assert note.cause == "power_drift" and note.remedy == REMEDIES["power_drift"]
    assert "responsivity changes with the wavelength" in str(note)


@pytest.mark.slow
def test_a_wide_band_fit_of_too_low_a_map_order_is_told_to_raise_it():
    sweep, _ = Scenario(seed=2, spectral="sin", dispersion_s2=1e-26, **WIDE).tables()
    _, notes = fitted(
        wm.WidebandCalibrator(phase_order=2, map_order=0), ports(sweep), sweep["frequency_hz"]
    )
    note = only_cause(notes)
    assert note.cause == "dispersion"
    assert "higher map_order (this fit has 0)" in note.remedy
    assert "--map-order" in warning_text(note).rpartition("(options: ")[2]


# ---------------------------------------------------------------------- rounded axes
def test_a_wavelength_rounded_by_a_spreadsheet_is_a_quantised_axis():
    """The issue's file: the wavelength column rounded to 0.001 nm, 398 distinct values in
    2001 rows. Named with its numbers and the remedy; no ``phase_drift`` beside it."""
    (_, notes), recorded = rounded_fit("nm", 3)
    assert np.unique(recorded).size == 398
    note = only_cause(notes)
    assert note.cause == "quantised_axis" and note.remedy == REMEDIES["quantised_axis"]
    text = str(note)
    assert "398 distinct values in 2001 readings" in text
    assert "grid of 0.001 nm in wavelength" in text and "median step 125 MHz" in text
    assert "spreadsheet" in note.remedy and "--" not in text
    # rounding to a 125 MHz step leaves 125 / sqrt(12) = 36 MHz RMS
    assert "(36" in text or "(35" in text
    assert warning_text(note) == f"[quantised_axis] {note}"  # no option remedies it


@pytest.mark.slow
def test_a_grid_finer_than_the_sweep_step_is_found_too():
    """Rounded to 0.0001 nm (12.5 MHz) where the sweep steps 25 MHz: no value repeats, but
    every one lies on the grid and the residual follows it."""
    (_, notes), recorded = rounded_fit("nm", 4)
    assert np.unique(recorded).size == recorded.size
    note = only_cause(notes)
    assert note.cause == "quantised_axis" and "grid of 0.0001 nm" in str(note)


@pytest.mark.slow
def test_a_frequency_rounded_to_100_mhz_is_a_quantised_axis():
    (_, notes), _ = rounded_fit("THz", 4)
    note = only_cause(notes)
    assert note.cause == "quantised_axis" and "grid of 100 MHz in frequency" in str(note)


@pytest.mark.slow
def test_a_stepped_laser_with_repeated_readings_at_exact_set_points_warns_nothing():
    """The control: five readings per set point, the set points on a 100 MHz grid and the
    recorded values exact: the axis repeats and lies on a grid, but the residual does not
    follow its steps."""
    device = wm.Interferometer.table1(3, seed=5)
    points = np.round(device.sweep_hz(400) / 1e8) * 1e8
    frequency = np.repeat(points, 5)
    _, notes = fitted(wm.Calibrator(), device.powers(frequency, POWER_W, NOISE_W, rng=6), frequency)
    assert notes == []


# ---------------------------------------------------------------------- clean sweeps
@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_clean_plain_and_thermal_sweeps_warn_nothing(seed):
    assert scenario_fit(wm.Calibrator(), seed=seed)[1] == []
    thermal = {"platform": "sin", "ramp_k": (290.0, 300.0), "repeat": 5}
    assert scenario_fit(wm.ThermalCalibrator(), seed=seed, **thermal)[1] == []


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
def test_the_wide_band_pages_sweep_calibrated_wide_band_warns_nothing(seed):
    cal, notes = scenario_fit(
        wm.WidebandCalibrator(), seed=seed, spectral="sin", dispersion_s2=1e-26, **WIDE
    )
    assert notes == [], [str(note) for note in notes]


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
def test_a_clean_cascade_warns_nothing(seed):
    """The cascade page's device (SiN slopes on every stage): its coarsest stage, swept over
    less than its FSR, takes a map that changes with frequency, which its slopes need; it
    then fits to the noise and nothing warns (issue 29 saw ``other_misfit`` there)."""
    fsrs = (5e12, 500e9, 50e9)
    cal, notes = scenario_fit(
        wm.CascadeCalibrator(fsr_hz=fsrs),
        seed=seed,
        cascade_fsrs_hz=fsrs,
        spectral="sin",
        samples=8000,
    )
    assert notes == [], [str(note) for note in notes]
    assert cal.stages_[0].map_order_ >= 1
    assert cal.model_error_hz_[0] == 0.0


def test_a_sweep_within_one_or_two_fsrs_of_sloped_couplers_takes_a_map_slope():
    """A wide-band fit over 1.8 FSRs of couplers that change 30 %/THz: the sweep's F test
    takes map order 1 (allowed on one or two FSR windows), the residual is noise and the
    test readings reach the bound with honest uncertainties. With a constant map they were
    4-9x the bound."""
    scenario = Scenario(
        seed=1,
        span_fsr=1.8,
        samples=3600,
        coupler_slope_sigma_per_thz=0.3,
        responsivity_slope_sigma_per_thz=0.15,
        test=4000,
    )
    sweep, test = scenario.tables()
    cal, notes = fitted(wm.WidebandCalibrator(), ports(sweep), sweep["frequency_hz"])
    assert notes == [] and cal.map_order_ == 1
    truth = test["true_frequency_hz"]
    error = cal.predict(ports(test), coarse_hz=truth) - truth
    bound = np.sqrt(np.mean(cal.crlb_hz(ports(test), coarse_hz=truth, frequency_hz=truth) ** 2))
    z = error / cal.frequency_std_hz(ports(test), coarse_hz=truth)
    # the bound times sqrt(1 + c / N) for c = 3 (J + 1) map columns per port learned from N
    # readings; 4000 test readings know an RMS or a spread to 1 / sqrt(2 x 4000) = 1.1 %:
    # 5 of those either side
    learned = np.sqrt(1.0 + 3.0 * (cal.map_order_ + 1) / 3600)
    assert np.sqrt(np.mean(error**2)) < (1.0 + 5 * 0.011) * bound * learned
    assert abs(np.std(z) - 1.0) < 5 * 0.011


def test_every_cause_has_a_remedy_and_a_row_in_the_warnings_table():
    from pathlib import Path

    table = (Path(__file__).parent.parent / "docs" / "user-guide" / "sweep.rst").read_text()
    for cause in CAUSES:
        assert f"   * - ``{cause}``" in table, cause
        if cause != "other_misfit":
            assert REMEDIES[cause], cause

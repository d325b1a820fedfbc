"""
Absolute accuracy from a gas cell: correct the laser's axis, or need none
=========================================================================

A tunable laser at its +-10 pm specification sweeps a 3-port Table 1 meter across 1 THz of a
*simulated* molecular band (``hcn-like``: its lines are a simulation, not real HCN lines;
for a real cell read its certified table with ``wm.ReferenceLines.read_csv``), and a
reference cell is recorded beside the ports. A calibration on the laser's recorded axis
inherits the laser's error, hundreds of MHz; the same ``fit`` given the cell channel and
its line table corrects the axis between the lines with the meter's own phase, and given
no axis at all (``frequency_hz=None`` and the band) makes one from the lines. Both state
their absolute uncertainty: ``frequency_std_hz(..., absolute=True)``.
``benchmarks/absolute.py`` (``make absolute``) is the full study.
"""

import warnings

import matplotlib.pyplot as plt
import numpy as np

import wavemeter as wm
from wavemeter.simulation import ReferenceCell, laser_sweep

BAND_HZ = (193.9e12, 194.9e12)  # holds the band's origin gap: the lines' pattern is unique
rng = np.random.default_rng(32)
cell = ReferenceCell.simulated(rng=1)
sweep = laser_sweep(BAND_HZ, 8000, "tls-spec", rng=2)
device = wm.Interferometer.table1(ports=3, seed=1)
powers = device.powers(sweep.true_hz, power_w=1e-3, noise_w=5e-7, rng=3)
channel = cell.transmission(sweep.true_hz, rng=4)  # the cell sees the true frequency
test_hz = rng.uniform(194.0e12, 194.8e12, 2000)
test = device.powers(test_hz, power_w=1e-3, noise_w=5e-7, rng=5)
cell_keywords = {
    "reference_transmission": channel,
    "reference_lines": cell.lines,
    "reference_pressure_pa": cell.nominal_pressure_pa,
    "reference_pressure_std_pa": cell.pressure_std_pa,
}

# %%
# Three calibrations of one sweep
# -------------------------------
# The learned calibrator reads within one FSR, so errors are taken modulo its FSR (in use
# a coarse value picks the fringe). The plain fit warns about the phase drift the laser's
# error leaves; it is kept quiet here and shown by its error.
with warnings.catch_warnings():
    warnings.simplefilter("ignore", wm.CalibrationWarning)
    plain = wm.Calibrator(50e9).fit(powers, sweep.recorded_hz)
corrected = wm.Calibrator(50e9).fit(powers, sweep.recorded_hz, **cell_keywords)
selfcal = wm.Calibrator(50e9).fit(powers, None, band_hz=BAND_HZ, **cell_keywords)


def error_hz(calibration):
    fsr = calibration.fsr_hz_
    return (calibration.predict(test) - test_hz + fsr / 2) % fsr - fsr / 2


def rms(values):
    return float(np.sqrt(np.mean(np.square(values))))


for name, calibration in (("plain", plain), ("corrected", corrected), ("self-cal", selfcal)):
    stated = ""
    if calibration.uncertainty_budget_ is not None:
        stated = rms(calibration.frequency_std_hz(test, absolute=True)) / 1e6
        stated = f", stated {stated:.1f} MHz"
    print(f"{name:10s} absolute error {rms(error_hz(calibration)) / 1e6:8.1f} MHz RMS{stated}")
record = corrected.axis_correction_
print(f"lines: {record.labels[0]} to {record.labels[-1]} ({len(record.labels)}), {record.detail}")
for term, value_hz in corrected.uncertainty_budget_.rms_hz().items():
    print(f"  {term:20s} {value_hz / 1e6:6.2f} MHz")

# %%
# The cell, the correction and the errors
# ---------------------------------------
# Left: the cell channel on the corrected axis (its envelope) with the fitted line centres.
# Middle: the correction (corrected less recorded axis) with its standard uncertainty, and
# the truth (true less recorded). Right: the test readings' absolute errors with the
# stated absolute uncertainty (2 sigma).
fig, (left, middle, right) = plt.subplots(1, 3, figsize=(13, 4))
offset_hz = np.mean(BAND_HZ)
left.fill_between(
    (record.cell_frequency_hz - offset_hz) / 1e9, record.cell_low, record.cell_high, color="C0"
)
for center_hz in record.line_fitted_hz:
    left.axvline((center_hz - offset_hz) / 1e9, color="C3", lw=0.6)
left.set_xlabel(f"frequency - {offset_hz / 1e12:.2f} THz (GHz)")
left.set_ylabel("cell transmission")
by_truth = np.argsort(sweep.true_hz)
middle.plot(
    (sweep.true_hz[by_truth] - offset_hz) / 1e9,
    -sweep.axis_error_hz[by_truth] / 1e6,
    "k",
    lw=3,
    alpha=0.3,
    label="truth",
)
grid_ghz = (record.frequency_hz - offset_hz) / 1e9
middle.plot(grid_ghz, record.shift_hz / 1e6, "C1", label="correction")
middle.fill_between(
    grid_ghz,
    (record.shift_hz - record.shift_std_hz) / 1e6,
    (record.shift_hz + record.shift_std_hz) / 1e6,
    color="C1",
    alpha=0.3,
)
middle.set_xlabel(f"frequency - {offset_hz / 1e12:.2f} THz (GHz)")
middle.set_ylabel("axis correction (MHz)")
middle.legend()
order = np.argsort(test_hz)
for name, calibration, color in (("corrected", corrected, "C2"), ("self-cal", selfcal, "C4")):
    right.plot(
        (test_hz[order] - offset_hz) / 1e9,
        error_hz(calibration)[order] / 1e6,
        ".",
        ms=2,
        color=color,
        label=name,
    )
band = 2 * corrected.frequency_std_hz(test, absolute=True)[order] / 1e6
right.fill_between((test_hz[order] - offset_hz) / 1e9, -band, band, color="0.8", label="2 sigma")
right.set_xlabel(f"frequency - {offset_hz / 1e12:.2f} THz (GHz)")
right.set_ylabel("absolute error (MHz)")
right.legend(markerscale=4)
fig.tight_layout()
plt.show()

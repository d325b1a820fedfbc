"""
A first calibration
===================

Sweep a tunable laser over one FSR, record the port powers, learn a calibration
(:class:`wavemeter.Calibrator`), and turn later readings into frequency, each with its
standard deviation and quality flags. The device here is simulated: a 3x3 MMI meter with
the impairments of the paper's Table 1 (:meth:`wavemeter.Interferometer.table1`).
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import wavemeter as wm

# %%
# Calibrate
# ---------
# The sweep: 2,001 known frequencies over one FSR about 193.4 THz, and the port powers
# (W) the device gives at 1 mW with 5e-7 W of detector noise. ``fit`` learns the FSR
# (searched within +-20 % of the design value) and the map ``A`` (3 x 3).
dev = wm.Interferometer.table1(ports=3, seed=7)
f_hz = dev.sweep_hz(2001)
P = dev.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (2001, 3) port powers in W

cal = wm.Calibrator(fsr_hz=50e9, fsr_tolerance=0.2).fit(P, f_hz)
print(cal.summary())

# %%
# Save, load, read
# ----------------
# A calibration file is versioned JSON; a loaded calibration predicts bit for bit what the
# saved one did. ``predict`` gives frequency (Hz), ``frequency_std_hz`` each reading's
# standard deviation (the calibration's own uncertainty included), ``flags`` a bit mask
# per reading (0: nothing to report).
path = Path(tempfile.mkdtemp()) / "chip.wmcal.json"
cal.save(path)
cal = wm.load_calibration(path)

rng = np.random.default_rng(2)
test_hz = dev.center_hz + (rng.random(5000) - 0.5) * 0.98 * dev.true_fsr_hz
test = dev.powers(test_hz, power_w=0.5e-3, noise_w=5e-7, rng=rng)  # at half the power
found_hz = cal.predict(test)
std_hz = cal.frequency_std_hz(test)
error_hz = found_hz - test_hz
print(f"RMS error {np.sqrt(np.mean(error_hz**2)) / 1e6:.2f} MHz")
print(f"median stated std {np.median(std_hz) / 1e6:.2f} MHz; z std {np.std(error_hz / std_hz):.3f}")
flags = cal.flags(test)
for flag in wm.ReadingFlag:
    if np.any(flags & flag):
        print(f"{flag.name}: {np.count_nonzero(flags & flag)} of {flags.size} readings")

# %%
# Every reading is flagged ``POWER_RANGE``: it is at half the calibrated power, and this
# calibration could not learn the detectors' dark offsets (no dark readings, no monitored
# power that varied). At constant power an offset is absorbed into the map exactly and
# costs accuracy only at other powers, so readings more than 5 % away from the calibrated
# power are flagged. Give ``fit`` dark readings (``dark_w``) and the margin is a factor 2.

# %%
# The physical limit
# ------------------
# The Cramer-Rao bound of each test reading, from the true device (at the test power):
# what no method can beat with this detector noise.
phase = wm.model.delay_phase_rad(test_hz, dev.center_hz, dev.delay_s)
crlb_hz = wm.crlb_frequency_std(dev.true_map(), phase, 0.5e-3, 5e-7, dev.true_fsr_hz)
print(f"RMS error / CRLB = {np.sqrt(np.mean(error_hz**2) / np.mean(crlb_hz**2)):.3f}")

# %%
# The figure: the calibration sweep (the fringes of the three ports) and the errors of the
# test readings with the band of two stated standard deviations.
order = np.argsort(test_hz)
fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
top.plot((f_hz - dev.center_hz) / 1e9, P * 1e3)
top.set_ylabel("port power (mW)")
top.set_title("calibration sweep: 3 ports over one FSR")
x_ghz = (test_hz[order] - dev.center_hz) / 1e9
bottom.plot(x_ghz, error_hz[order] / 1e6, ".", ms=1, label="error of 5,000 test readings")
bottom.fill_between(
    x_ghz, -2 * std_hz[order] / 1e6, 2 * std_hz[order] / 1e6, color="0.8", label="2 x stated std"
)
bottom.set_xlabel("frequency - centre (GHz)")
bottom.set_ylabel("error (MHz)")
bottom.legend(markerscale=8, loc="upper right")
fig.tight_layout()

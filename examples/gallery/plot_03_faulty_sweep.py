"""
Warnings on a faulty sweep, flags on bad readings
=================================================

A sweep whose source power drifts by +-20 % while nothing records it departs from the
model. The calibration still fits, and says so: a :class:`wavemeter.CalibrationWarning`
with the cause ``power_drift``, the evidence and the remedy (record the power with a
monitor). With the monitor's readings given to ``fit`` the same sweep calibrates at the
Cramer-Rao bound. Every later reading also carries flag bits
(:class:`wavemeter.ReadingFlag`) and a standard deviation: here a glitch, a reading at
three times the calibrated power and a dark reading are flagged.
"""

import warnings

import matplotlib.pyplot as plt
import numpy as np

import wavemeter as wm
from wavemeter.simulation import slow_power_drift

dev = wm.Interferometer.table1(ports=3, seed=7)
rng = np.random.default_rng(3)
f_hz = dev.sweep_hz(2001)
power_w = 1e-3 * slow_power_drift(f_hz.size, 0.2, rng=rng)  # the source drifts +-20 %
sweep = dev.powers(f_hz, power_w=power_w, noise_w=5e-7, rng=rng)

# %%
# The fit warns
# -------------
# ``warnings.catch_warnings`` collects what ``fit`` emits; each warning names its cause
# (one of ``wavemeter.calibration.misfit.CAUSES`` or a calibrator's own) and a remedy.
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    drifting = wm.Calibrator(fsr_hz=50e9).fit(sweep, f_hz)
for note in caught:
    print(f"[{note.message.cause}] {note.message}\n  remedy: {note.message.remedy}\n")

# %%
# The remedy: a power monitor
# ---------------------------
# The monitor reads a fixed fraction of the source power; the calibration scales each
# reading's object vector by it.
monitored = wm.Calibrator(fsr_hz=50e9).fit(sweep, f_hz, power_monitor_w=dev.monitor(power_w))
test_hz = dev.center_hz + (rng.random(5000) - 0.5) * 0.98 * dev.true_fsr_hz
test = dev.powers(test_hz, power_w=1e-3, noise_w=5e-7, rng=rng)
phase = wm.model.delay_phase_rad(test_hz, dev.center_hz, dev.delay_s)
crlb_hz = wm.crlb_frequency_std(dev.true_map(), phase, 1e-3, 5e-7, dev.true_fsr_hz)
for name, cal in (("no monitor", drifting), ("monitor", monitored)):
    error_hz = wm.frequency_error_hz(cal.predict(test), test_hz, cal.fsr_hz_)
    ratio = np.sqrt(np.mean(error_hz**2) / np.mean(crlb_hz**2))
    print(f"{name:>10}: RMS/CRLB {ratio:.2f}")

# %%
# Flags on readings
# -----------------
# Three good readings, then a glitch (one port 30 % high), a reading at three times the
# calibrated power and one with the light off. ``flags`` returns one integer per reading;
# its bits are ``ReadingFlag`` members.
probe_hz = dev.center_hz + np.array([-10e9, 0.0, 10e9, 5e9, 5e9, 5e9])
probe = dev.powers(probe_hz, power_w=1e-3, noise_w=5e-7, rng=rng)
probe[3, 1] *= 1.3
probe[4] *= 3.0
probe[5] = dev.powers(probe_hz[5:], power_w=1e-9, noise_w=0.0)
for row, bits in enumerate(monitored.flags(probe)):
    names = [flag.name for flag in wm.ReadingFlag if bits & flag] or ["-"]
    print(f"reading {row}: flags {int(bits):2d} {' '.join(names)}")

# %%
# The figure: the drifting source power during the sweep, and the test errors of both
# calibrations against the band of two Cramer-Rao standard deviations.
fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5.5))
top.plot((f_hz - dev.center_hz) / 1e9, power_w * 1e3)
top.set_xlabel("sweep frequency - centre (GHz)")
top.set_ylabel("source power (mW)")
top.set_title("the sweep: source power drifting +-20 %, unrecorded")
order = np.argsort(test_hz)
x_ghz = (test_hz[order] - dev.center_hz) / 1e9
for name, cal, colour in (("no monitor", drifting, "C1"), ("monitor", monitored, "C0")):
    error_hz = wm.frequency_error_hz(cal.predict(test), test_hz, cal.fsr_hz_)[order]
    bottom.plot(x_ghz, error_hz / 1e6, ".", ms=1, color=colour, label=name)
bottom.fill_between(x_ghz, -2 * crlb_hz[order] / 1e6, 2 * crlb_hz[order] / 1e6, color="0.8")
bottom.set_xlabel("test frequency - centre (GHz)")
bottom.set_ylabel("error (MHz)")
bottom.legend(markerscale=8)
fig.tight_layout()

"""
Thermal calibration: error against chip temperature
===================================================

A silicon-nitride chip's fringes move by about 2.6 GHz per kelvin. A plain calibration made
at 293 K is then wrong by gigahertz a few kelvin away; re-anchored on readings of one
reference line at the new temperature (:meth:`wavemeter.Calibrator.reanchor`) it is back
near the bound; a thermal calibration (:class:`wavemeter.ThermalCalibrator`) learned from
sweeps at four temperatures reads every temperature at the bound, given each reading's
temperature. ``benchmarks/thermal.py`` (``make thermal``) is the full study.
"""

import warnings

import matplotlib.pyplot as plt
import numpy as np

import wavemeter as wm

dev = wm.Interferometer.table1(ports=3, seed=7).with_thermal("sin")
rng = np.random.default_rng(5)
POWER_W, NOISE_W, SENSOR_STD_K = 1e-3, 5e-7, 1e-3

# %%
# Calibrate
# ---------
# Four sweeps of one FSR at 290, 291.5, 295 and 300 K, concatenated, with each reading's
# temperature (as a sensor reads it, 1 mK noise); a plain calibration on the 293 K sweep.
sweep_hz, sweeps, temperatures = [], [], []
for temperature_k in (290.0, 291.5, 295.0, 300.0):
    f_hz = dev.sweep_hz(1000)
    sweep_hz.append(f_hz)
    sweeps.append(dev.powers(f_hz, POWER_W, NOISE_W, rng=rng, temperature_k=temperature_k))
    temperatures.append(temperature_k + SENSOR_STD_K * rng.standard_normal(f_hz.size))
thermal = wm.ThermalCalibrator(temperature_std_k=SENSOR_STD_K).fit(
    np.vstack(sweeps), np.concatenate(sweep_hz), temperature_k=np.concatenate(temperatures)
)
f_hz = dev.sweep_hz(1000)
plain = wm.Calibrator(fsr_hz=50e9).fit(
    dev.powers(f_hz, POWER_W, NOISE_W, rng=rng, temperature_k=293.0), f_hz
)
print(thermal.summary())

# %%
# Read at other temperatures
# --------------------------
# At each test temperature: 2,000 readings at random frequencies. The plain calibration is
# also re-anchored on 50 readings of a line at the centre frequency at that temperature.
# Errors are taken modulo the FSR (a plain calibration cannot tell whole FSRs).
rows = []
for temperature_k in np.arange(284.0, 306.5, 2.0):
    test_hz = dev.center_hz + (rng.random(2000) - 0.5) * 0.98 * dev.true_fsr_hz
    test = dev.powers(test_hz, POWER_W, NOISE_W, rng=rng, temperature_k=temperature_k)
    sensed_k = temperature_k + SENSOR_STD_K * rng.standard_normal(test_hz.size)
    line = dev.powers(
        np.full(50, dev.center_hz), POWER_W, NOISE_W, rng=rng, temperature_k=temperature_k
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        anchored = plain.reanchor(line, dev.center_hz)
    estimates = {
        "plain, 293 K": plain.predict(test),
        "plain, re-anchored": anchored.predict(test),
        "thermal": thermal.predict(test, temperature_k=sensed_k),
    }
    rms = {
        name: np.sqrt(np.mean(wm.frequency_error_hz(value, test_hz, plain.fsr_hz_) ** 2))
        for name, value in estimates.items()
    }
    stated = np.sqrt(np.mean(thermal.frequency_std_hz(test, temperature_k=sensed_k) ** 2))
    rows.append((temperature_k, rms, stated))
    print(f"{temperature_k:.0f} K: " + ", ".join(f"{k} {v / 1e6:.4g} MHz" for k, v in rms.items()))

# %%
# The figure: RMS error against chip temperature (log scale); the grey band is the span
# of the thermal calibration's sweeps, the dashed line its stated standard deviation.
fig, ax = plt.subplots(figsize=(7, 4.2))
temps = [row[0] for row in rows]
for name, marker in (("plain, 293 K", "s"), ("plain, re-anchored", "^"), ("thermal", "o")):
    ax.semilogy(temps, [row[1][name] / 1e6 for row in rows], marker + "-", label=name)
ax.semilogy(temps, [row[2] / 1e6 for row in rows], "k--", label="thermal: stated std")
ax.axvspan(290, 300, color="0.9", zorder=0)
ax.set_xlabel("chip temperature (K)")
ax.set_ylabel("RMS frequency error (MHz)")
ax.set_title("silicon nitride, 3 ports, 1 mK sensor")
ax.legend()
fig.tight_layout()

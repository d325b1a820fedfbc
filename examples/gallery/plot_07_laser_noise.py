"""
A laser's frequency noise: PSD, linewidth and Allan deviation
=============================================================

A simulated laser with 100 kHz of white frequency noise (Lorentzian linewidth
``pi h0``), flicker FM and a slow drift is read at 10 MHz by a 3-port meter with a 500 MHz
FSR. :func:`wavemeter.analysis.frequency_noise` takes the unwrapped readings and each
reading's standard deviation, subtracts the meter's own white floor, corrects the
interferometer's delay, fits the power law ``h0 + h_-1 / f + h_-2 / f^2`` and gives the
linewidths, the drift and the Allan family, each with its uncertainty. The simulated truth
is drawn on top. ``benchmarks/noise.py`` (``make noise``) is the full study.
"""

import matplotlib.pyplot as plt
import numpy as np

import wavemeter as wm
from wavemeter.analysis import frequency_noise, power_law_deviations, power_law_psd_hz2_per_hz
from wavemeter.simulation import laser_frequency_hz

RATE_HZ = 10e6
LASER = {"white_fm_hz2_per_hz": 1e5 / np.pi, "flicker_fm_hz2": 4e8, "drift_hz_per_s": 1e8}

dev = wm.Interferometer.table1(ports=3, seed=7, fsr_hz=500e6)
f_hz = dev.sweep_hz(2001)
cal = wm.Calibrator(fsr_hz=500e6).fit(dev.powers(f_hz, 1e-3, 5e-7, rng=1), f_hz)

# %%
# Read the laser through the meter
# --------------------------------
# One interferometer reads modulo its FSR: unwrap with period FSR before the analysis.
truth_hz = laser_frequency_hz(2**17, RATE_HZ, center_hz=dev.center_hz, rng=3, **LASER)
powers = dev.powers(truth_hz, power_w=1e-3, noise_w=5e-7, rng=4)
readings_hz = np.unwrap(cal.predict(powers), period=cal.fsr_hz_)
result = frequency_noise(
    readings_hz, RATE_HZ, meter_std_hz=cal.frequency_std_hz(powers), fsr_hz=cal.fsr_hz_
)
r = result
true_lorentzian_hz = np.pi * LASER["white_fm_hz2_per_hz"]
print(f"meter floor     {r.meter_floor_hz2_per_hz:.4g} Hz^2/Hz")
print(f"Lorentzian      {r.lorentzian_linewidth_hz:.4g} +- {r.lorentzian_linewidth_std_hz:.2g} Hz")
print(f"  (true         {true_lorentzian_hz:.4g} Hz)")
print(f"flicker FM      {r.flicker_fm_hz2:.3g} +- {r.flicker_fm_std_hz2:.2g} Hz^2 (true 4e8)")
print(f"drift           {r.drift_hz_per_s:.4g} +- {r.drift_std_hz_per_s:.2g} Hz/s (true 1e8)")
print(f"beta linewidth  {r.beta_linewidth_hz:.4g} +- {r.beta_linewidth_std_hz:.2g} Hz")
print("warnings:", result.warnings or "none")

# %%
# The PSD and the Allan deviation
# -------------------------------
# Left: the readings' PSD (band-averaged, with its confidence band), the meter's floor, the
# PSD with the floor removed and the delay corrected, and the laser's true PSD. Right:
# the overlapping Allan deviation of the fractional frequency with Greenhall's confidence
# intervals, and the analytic value of the laser plus the meter's floor.
truth_psd = power_law_psd_hz2_per_hz(
    result.psd_freqs_hz,
    white_fm_hz2_per_hz=LASER["white_fm_hz2_per_hz"],
    flicker_fm_hz2=LASER["flicker_fm_hz2"],
)
analytic = power_law_deviations(
    result.taus_s,
    result.center_frequency_hz,
    white_fm_hz2_per_hz=LASER["white_fm_hz2_per_hz"] + result.meter_floor_hz2_per_hz,
    flicker_fm_hz2=LASER["flicker_fm_hz2"],
    drift_hz_per_s=LASER["drift_hz_per_s"],
    rate_hz=RATE_HZ,
)
fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
left.fill_between(result.psd_freqs_hz, *result.psd_ci_hz2_per_hz, color="C0", alpha=0.25)
left.loglog(result.psd_freqs_hz, result.psd_hz2_per_hz, color="C0", label="readings")
left.axhline(result.meter_floor_hz2_per_hz, color="C3", ls=":", label="meter floor")
left.loglog(result.psd_freqs_hz, result.psd_corrected_hz2_per_hz, color="C2", label="floor removed")
left.loglog(result.psd_freqs_hz, truth_psd, "k--", label="laser (truth)")
left.set_xlabel("Fourier frequency (Hz)")
left.set_ylabel("frequency-noise PSD (Hz$^2$/Hz)")
left.legend()
low, high = result.adev_ci
right.errorbar(
    result.taus_s,
    result.adev,
    yerr=[result.adev - low, high - result.adev],
    fmt="o",
    ms=3,
    label="ADEV of the readings",
)
right.loglog(result.taus_s, analytic["adev"], "k--", label="analytic: laser + floor")
right.set_xscale("log")
right.set_yscale("log")
right.set_xlabel("averaging time (s)")
right.set_ylabel("Allan deviation (fractional)")
right.legend()
fig.tight_layout()

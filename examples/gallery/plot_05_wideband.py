"""
Wide band: the residual phase across 24 FSRs
============================================

Over a band of many FSRs the fringe phase is not linear in frequency (group-delay
dispersion of the delay imbalance) and the couplers and photodiodes change slowly with
wavelength. One plain calibration over the band leaves a parabola of residual phase and
warns ``dispersion``; :class:`wavemeter.WidebandCalibrator` fits a phase polynomial and a
map smooth in frequency, choosing their orders by cross-validation on held-out FSRs, and
leaves only noise. A silicon-nitride device with 25 times the preset's dispersion, 24 FSRs
of 400 readings (the command-line example of the user guide); ``benchmarks/wideband.py``
(``make wideband``) covers the whole C band.
"""

import dataclasses
import warnings

import matplotlib.pyplot as plt
import numpy as np

import wavemeter as wm

dev = wm.Interferometer.table1(ports=3, seed=7).with_spectral("sin", seed=1)
dev = dataclasses.replace(dev, dispersion_s2=25 * dev.dispersion_s2)  # 1e-26 s^2
f_hz = dev.center_hz + (np.arange(24 * 400) / 400 - 12) * dev.true_fsr_hz
sweep = dev.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)

# %%
# One plain calibration over the band warns
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    plain = wm.Calibrator(fsr_hz=50e9).fit(sweep, f_hz)
print("plain Calibrator warns:", [note.message.cause for note in caught])

# %%
# The wide-band calibration chooses its orders
band = wm.WidebandCalibrator().fit(sweep, f_hz)
print(f"phase order {band.phase_order_}, map order {band.map_order_}, {band.n_parameters_} numbers")
print("phase coefficients (delay s, dispersion s^2):", band.phase_coefficients_)
for candidate in band.diagnostics_["wideband"]["orders"]["candidates"]:
    print(
        f"  (P, J) = ({candidate['phase_order']}, {candidate['map_order']}):"
        f" held-out RMS {candidate['cv_rms_hz'] / 1e6:8.2f} MHz"
        + ("  <- chosen" if candidate["chosen"] else "")
    )

# %%
# Reading needs a coarse frequency within half an FSR (here the truth + 0.2 FSR)
rng = np.random.default_rng(2)
test_hz = f_hz.min() + rng.random(3000) * np.ptp(f_hz)
test = dev.powers(test_hz, power_w=1e-3, noise_w=5e-7, rng=rng)
found_hz = band.predict(test, coarse_hz=test_hz + 0.2 * dev.true_fsr_hz)
error_hz = found_hz - test_hz
std_hz = band.frequency_std_hz(test, coarse_hz=test_hz)
rms_mhz = np.sqrt(np.mean(error_hz**2)) / 1e6
print(f"RMS error {rms_mhz:.2f} MHz, z std {np.std(error_hz / std_hz):.3f}")

# %%
# The figure: the mean residual phase per FSR window. For the plain calibration: its
# retrieved phase minus its linear model phase; for the wide-band one: its diagnostics.
model_rad = 2 * np.pi * (f_hz - plain.center_hz_) / plain.fsr_hz_
residual = np.angle(np.exp(1j * (plain.phase(sweep) - model_rad)))
windows = np.floor((f_hz - f_hz.min()) / plain.fsr_hz_).astype(int)
plain_centres = [f_hz[windows == w].mean() for w in np.unique(windows)]
plain_means = [residual[windows == w].mean() for w in np.unique(windows)]
rows = band.diagnostics_["wideband"]["residual_phase"]
fig, ax = plt.subplots(figsize=(7, 4))
ax.plot(
    (np.array(plain_centres) - dev.center_hz) / 1e12, plain_means, "s-", label="plain Calibrator"
)
ax.plot(
    (np.array([row["center_hz"] for row in rows]) - dev.center_hz) / 1e12,
    [row["mean_rad"] for row in rows],
    "o-",
    label=f"WidebandCalibrator (P={band.phase_order_}, J={band.map_order_})",
)
ax.set_xlabel("frequency - centre (THz)")
ax.set_ylabel("mean residual phase per FSR (rad)")
ax.set_title("24 FSRs, group-delay dispersion 1e-26 s^2")
ax.legend()
fig.tight_layout()

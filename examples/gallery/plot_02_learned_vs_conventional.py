"""
Calibration vs conventional vs the Cramer-Rao bound, device by device
=====================================================================

Twelve simulated devices with the impairments of the paper's Table 1 (3 and 4 ports, six
of each), each calibrated on 1,001 readings over one FSR and read on 5,000 fresh readings
at the same noise (5e-7 W at 1 mW). The learned calibration
(:class:`wavemeter.Calibrator`) is compared with the conventional method
(:class:`wavemeter.ConventionalCalibrator`, the ideal coupler's design phases) and with
the Cramer-Rao bound of each device (:func:`wavemeter.crlb_frequency_std`), reading by
reading. ``benchmarks/precision.py`` (``make bench``) is the full version: 50 devices per
port count, 20,000 test readings.
"""

import matplotlib.pyplot as plt
import numpy as np

import wavemeter as wm

POWER_W, NOISE_W = 1e-3, 5e-7
rows = []
for ports in (3, 4):
    for seed in range(6):
        dev = wm.Interferometer.table1(ports=ports, seed=seed)
        rng = np.random.default_rng(100 + seed)
        f_hz = dev.sweep_hz(1001)
        sweep = dev.powers(f_hz, power_w=POWER_W, noise_w=NOISE_W, rng=rng)
        learned = wm.Calibrator(fsr_hz=50e9).fit(sweep, f_hz)
        conventional = wm.ConventionalCalibrator(50e9, dev.design_port_phases_rad).fit(sweep, f_hz)
        test_hz = dev.center_hz + (rng.random(5000) - 0.5) * 0.98 * dev.true_fsr_hz
        test = dev.powers(test_hz, power_w=POWER_W, noise_w=NOISE_W, rng=rng)
        phase = wm.model.delay_phase_rad(test_hz, dev.center_hz, dev.delay_s)
        crlb_hz = wm.crlb_frequency_std(dev.true_map(), phase, POWER_W, NOISE_W, dev.true_fsr_hz)
        rms = {
            name: np.sqrt(
                np.mean(wm.frequency_error_hz(cal.predict(test), test_hz, cal.fsr_hz_) ** 2)
            )
            for name, cal in (("learned", learned), ("conventional", conventional))
        }
        rows.append(
            (ports, seed, rms["learned"], rms["conventional"], np.sqrt(np.mean(crlb_hz**2)))
        )

print("ports seed  learned MHz  conventional MHz  CRLB MHz  learned/CRLB  conv/learned")
for ports, seed, learned_hz, conventional_hz, crlb_hz in rows:
    print(
        f"{ports:5d} {seed:4d} {learned_hz / 1e6:12.3f} {conventional_hz / 1e6:17.1f}"
        f" {crlb_hz / 1e6:9.3f} {learned_hz / crlb_hz:13.3f} {conventional_hz / learned_hz:13.0f}"
    )
ratios = np.array([row[2] / row[4] for row in rows])
print(f"learned RMS / CRLB: median {np.median(ratios):.3f}, worst {ratios.max():.3f}")

# %%
# Each device's RMS error against its bound: the learned calibration sits on the bound
# (ratio about 1), the conventional method one to two orders of magnitude above it.
fig, ax = plt.subplots(figsize=(7, 4))
x = np.arange(len(rows))
ax.semilogy(x, [row[3] / 1e6 for row in rows], "s", color="C1", label="conventional")
ax.semilogy(x, [row[2] / 1e6 for row in rows], "o", color="C0", label="learned")
ax.semilogy(x, [row[4] / 1e6 for row in rows], "_", ms=18, color="k", label="CRLB")
ax.set_xticks(x, [f"{row[0]}p #{row[1]}" for row in rows], rotation=45)
ax.set_ylabel("RMS frequency error (MHz)")
ax.set_title("Table 1 devices: 3 and 4 ports, 5,000 test readings each")
ax.legend()
fig.tight_layout()

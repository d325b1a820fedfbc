"""Calibrate a simulated 3x3 wavelength meter and read frequencies from new port powers.

Run: ``.venv/bin/python examples/quickstart.py``
"""

import numpy as np

import wavemeter as wm

device = wm.Interferometer.table1(ports=3, seed=7)  # Table 1 impairments, drawn from seed 7
rng = np.random.default_rng(1)

sweep_hz = device.sweep_hz(2001)  # a calibration sweep over one FSR (Hz)
sweep_w = device.powers(sweep_hz, power_w=1e-3, noise_w=5e-7, rng=rng)  # port powers (W)
cal = wm.Calibrator(fsr_hz=50e9).fit(sweep_w, sweep_hz)
print(f"fitted FSR {cal.fsr_hz_ / 1e9:.6f} GHz (true {device.true_fsr_hz / 1e9:.6f} GHz)")

reading_hz = device.center_hz + np.array([-20e9, 1e9, 17.3e9])
readings_w = device.powers(reading_hz, power_w=0.5e-3, noise_w=5e-7, rng=rng)  # other power
for true_hz, found_hz in zip(reading_hz, cal.predict(readings_w), strict=True):
    print(
        f"true {true_hz / 1e12:.9f} THz  retrieved {found_hz / 1e12:.9f} THz  "
        f"error {(found_hz - true_hz) / 1e6:+.2f} MHz"
    )

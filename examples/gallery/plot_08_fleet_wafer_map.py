"""
Many chips: a wafer map from a fleet calibration
================================================

A wafer of 5 x 5 dies, each a Table 1 3x3 device with its own impairments, each swept
once into a CSV file named by its die position (``die_x03_y12.csv``).
:func:`wavemeter.fleet.calibrate_fleet` calibrates every file (here in this process,
``workers=0``; by default on a ``distributed.LocalCluster`` of one worker per core, or on a
running dask scheduler) and writes each calibration, a summary table and ``fleet.html``.
Two dies are faulty: one has a dead detector, one a file of noise only. The wafer map
colours each die by its RMS error on its own sweep over the Cramer-Rao bound.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import wavemeter as wm
from wavemeter.fleet import calibrate_fleet, die_position
from wavemeter.io import write_table

wafer = Path(tempfile.mkdtemp()) / "wafer7"
wafer.mkdir()
rng = np.random.default_rng(11)
for x in range(5):
    for y in range(5):
        dev = wm.Interferometer.table1(ports=3, seed=100 * x + y)
        f_hz = dev.sweep_hz(800)
        powers = dev.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=rng)
        if (x, y) == (1, 4):
            powers[:, 2] = 5e-7 * rng.standard_normal(f_hz.size) + 2e-6  # a dead detector
        if (x, y) == (4, 1):
            powers = np.abs(1e-4 + 5e-7 * rng.standard_normal(powers.shape))  # no fringes
        columns = {"frequency_hz": f_hz} | {f"p{j + 1}_w": powers[:, j] for j in range(3)}
        write_table(wafer / f"die_x{x:02d}_y{y:02d}.csv", columns)

# %%
# Calibrate the fleet
# -------------------
# The keyword arguments are the calibration's options (those of ``wavemeter calibrate``).
result = calibrate_fleet(
    sorted(wafer.glob("*.csv")), wafer.parent / "wafer7-cal", workers=0, fsr_hz=50e9
)
print("wrote", result.summary_csv.name, result.summary_parquet.name, result.page.name)
for row in result.rows:  # one DeviceResult per file, in order
    if not row.ok or row.warnings:
        print(f"{row.device}: {row.status}; warnings {row.warnings}; {row.error or ''}"[:200])
ok = np.array([row.ok for row in result.rows])
ratio = np.array([row.crlb_ratio for row in result.rows])
x, y = np.array([die_position(row.device) for row in result.rows]).T
print(f"{ok.sum()} of {ok.size} calibrated; median RMS/CRLB {np.median(ratio[ok]):.3f}")

# %%
# The wafer map
# -------------
# One square per die at its position, coloured by RMS/CRLB; a cross marks a failed die.
fig, ax = plt.subplots(figsize=(5.5, 4.8))
shown = ax.scatter(
    x[ok],
    y[ok],
    c=ratio[ok],
    marker="s",
    s=900,
    cmap="viridis",
)
ax.scatter(x[~ok], y[~ok], marker="x", s=300, color="C3", label="failed")
fig.colorbar(shown, label="calibration RMS / CRLB")
ax.set_xlabel("die x")
ax.set_ylabel("die y")
ax.set_xlim(-0.7, 4.7)
ax.set_ylim(-0.7, 4.7)
ax.set_aspect("equal")
ax.legend(loc="upper right")
ax.set_title("wafer7: 25 dies")
fig.tight_layout()

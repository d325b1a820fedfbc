"""
Bad input: errors that say what to do, invalid rows, refused files
==================================================================

Files from the lab are imperfect. A sweep logged by a power meter in nm and dBm has a
cell left empty and the meter's no-reading code (-200 dBm) in another.
Reading it is an :class:`wavemeter.InputError` naming the file, the lines and the remedy;
``allow_invalid=True`` (``--drop-invalid`` on the command line) keeps the rows, flags them
with their reasons and the calibration skips them. The command line turns every such error
into one ``error:`` line and exit code 2, with no traceback and no partial output. A
design FSR typed without its unit is refused before any work.
"""

import contextlib
import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import wavemeter as wm
from wavemeter.cli import main
from wavemeter.io import read_table

dev = wm.Interferometer.table1(ports=3, seed=7)
f_hz = dev.sweep_hz(1001)
powers = dev.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
wavelength_nm = 299792458.0 / f_hz * 1e9
dbm = 10 * np.log10(powers / 1e-3)
lines = ["wavelength_nm,p1_dBm,p2_dBm,p3_dBm"]
lines += [
    f"{w:.17g},{a:.17g},{b:.17g},{c:.17g}" for w, (a, b, c) in zip(wavelength_nm, dbm, strict=True)
]
lines[101] = lines[101].rsplit(",", 1)[0] + ","  # an empty cell (file line 101)
lines[402] = lines[402].rsplit(",", 1)[0] + ",-200"  # the meter's no-reading code
folder = Path(tempfile.mkdtemp())
scan = folder / "scan.csv"
scan.write_text("\n".join(lines) + "\n")

# %%
# The library raises, naming lines and what to do
try:
    read_table(scan)
except wm.WavemeterError as error:
    print(f"{type(error).__name__} (parameter={error.parameter!r}):\n{error}")

# %%
# Keep the rows, flagged with their reasons; the calibration skips them
table = read_table(scan, allow_invalid=True)
print(table.describe_invalid())
valid = table.valid_only()
cal = wm.Calibrator(fsr_hz=50e9).fit(valid.powers_w, valid.x_hz)
print(f"calibrated on {valid.n_rows} of {table.n_rows} rows: FSR {cal.fsr_hz_ / 1e9:.4f} GHz")

# %%
# The command line: one ``error:`` line, exit code 2, no output file
with contextlib.redirect_stderr(sys.stdout):
    code = main(["calibrate", str(scan), "-o", str(folder / "chip.wmcal.json"), "--quiet"])
    print("exit code", code, "| output written:", (folder / "chip.wmcal.json").exists())
    code = main(["calibrate", str(scan), "-o", str(folder / "chip.wmcal.json"), "--fsr", "50"])
    print("exit code", code)
    code = main(
        ["calibrate", str(scan), "-o", str(folder / "chip.wmcal.json"), "--drop-invalid", "--quiet"]
    )
    print("exit code", code, "| output written:", (folder / "chip.wmcal.json").exists())

# %%
# The figure: the logged sweep (dBm) with its two invalid rows marked.
fig, ax = plt.subplots(figsize=(7, 3.8))
shown = 10 * np.log10(np.clip(table.powers_w, 1e-12, None) / 1e-3)
ax.plot(table.x_hz / 1e12, shown, lw=0.8)
bad = table.invalid
ax.plot(
    table.x_hz[bad] / 1e12, np.full(bad.sum(), -20.0), "v", color="C3", ms=10, label="invalid rows"
)
ax.set_ylim(-30, 2)
ax.set_xlabel("frequency (THz)")
ax.set_ylabel("port power (dBm)")
ax.legend()
fig.tight_layout()

"""
The demo: learned vs conventional vs the Cramer-Rao bound
=========================================================

``wavemeter demo`` (``make demo``) simulates a 3x3 MMI wavelength meter with every
impairment of the paper's Table 1, calibrates it on a 2,001-point sweep over one FSR,
measures 20,000 test readings and prints the learned method, the conventional method and
the physical limit side by side. Here it runs in a temporary folder; the table is what the
command prints, the figure is drawn from the ``results.csv`` it writes.
"""

# %%
# Run the demo
# ------------
# The command line's entry point takes the arguments ``wavemeter`` would.
import json
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from wavemeter.cli import main

folder = Path(tempfile.mkdtemp()) / "wavemeter-demo"
exit_code = main(["demo", "--out", str(folder)])
print("exit code", exit_code, "| files:", ", ".join(sorted(p.name for p in folder.iterdir())))

# %%
# What it wrote
# -------------
# ``results.json`` holds the numbers of the table; ``results.csv`` one row per test reading:
# the true frequency, both methods' frequencies and the Cramer-Rao bound of that reading.
results = json.loads((folder / "results.json").read_text())
for method, numbers in results["methods"].items():
    ratio = numbers["rms_hz"] / results["crlb_rms_hz"]
    print(f"{method:>12}: RMS {numbers['rms_hz'] / 1e6:9.3f} MHz = {ratio:7.3f} x CRLB")

table = np.genfromtxt(folder / "results.csv", delimiter=",", names=True)
true_hz = table["true_frequency_hz"]
order = np.argsort(true_hz)
offset_ghz = (true_hz[order] - true_hz.mean()) / 1e9

# %%
# The errors across the FSR
# -------------------------
# The conventional method assumes an ideal coupler: its error is a systematic curve of
# hundreds of MHz. The learned calibration's error is noise within the band of two
# Cramer-Rao standard deviations of each reading.
fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
for ax, method, colour in ((top, "conventional", "C1"), (bottom, "learned", "C0")):
    error_mhz = (table[f"{method}_frequency_hz"] - true_hz)[order] / 1e6
    ax.plot(offset_ghz, error_mhz, ".", ms=1, color=colour, label=method)
    ax.set_ylabel("error (MHz)")
    ax.legend(loc="upper right", markerscale=8)
band_mhz = 2 * table["crlb_std_hz"][order] / 1e6
bottom.fill_between(offset_ghz, -band_mhz, band_mhz, color="0.8", label="2 x CRLB")
bottom.legend(loc="upper right", markerscale=8)
bottom.set_xlabel("frequency - centre (GHz)")
fig.suptitle("Table 1 3x3 device: 20,000 test readings")
fig.tight_layout()

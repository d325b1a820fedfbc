"""
Long records and live readout: ``measure_file`` and ``stream``
==============================================================

A record of port readings in a file is measured a chunk of rows at a time
(:func:`wavemeter.jobs.measure_file`, what ``wavemeter measure`` does): memory bounded by
the chunk, one output row per input row, in order, written atomically. A live source is
read one reading at a time with ``cal.stream(rows)`` (what ``wavemeter stream`` does): each
record holds the frequency, its standard deviation and the flags the moment its row
arrives. Here a laser steps through five set points and one reading is a glitch.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import wavemeter as wm
from wavemeter.io import write_table
from wavemeter.jobs import measure_file

dev = wm.Interferometer.table1(ports=3, seed=7)
f_hz = dev.sweep_hz(2001)
cal = wm.Calibrator(fsr_hz=50e9).fit(dev.powers(f_hz, 1e-3, 5e-7, rng=1), f_hz)

# %%
# A record in a file, measured in chunks
# --------------------------------------
rng = np.random.default_rng(2)
steps_hz = dev.center_hz + np.repeat([-15e9, -5e9, 0.0, 8e9, 16e9], 400)
record = dev.powers(steps_hz, power_w=1e-3, noise_w=5e-7, rng=rng)
record[1234, 0] *= 1.5  # a glitch: one port 50 % high
folder = Path(tempfile.mkdtemp())
time_s = np.arange(steps_hz.size) / 1e3
write_table(
    folder / "record.csv",
    {"time_s": time_s} | {f"p{j + 1}_mW": record[:, j] * 1e3 for j in range(3)},
)
summary = measure_file(cal, folder / "record.csv", folder / "f.csv", chunk_rows=500)
print(summary)
out = np.genfromtxt(folder / "f.csv", delimiter=",", names=True)
print("columns:", ", ".join(out.dtype.names))
for row in np.flatnonzero(out["flags"]):
    bits = int(out["flags"][row])
    print(f"row {row}: flags {bits} =", " | ".join(f.name for f in wm.ReadingFlag if bits & f))

# %%
# The same readings, live
# -----------------------
# ``rows`` may be any iterable, endless too (a socket, a serial line): each row is read
# only when its record is asked for.
live = cal.stream(iter(record))
first = [next(live) for _ in range(3)]
for reading in first:
    print(
        f"{reading.frequency_hz:.1f} Hz +- {reading.frequency_std_hz:.3g} Hz, flags {reading.flags}"
    )
streamed = first + list(live)
same = np.allclose([r.frequency_hz for r in streamed], out["frequency_hz"], rtol=0, atol=1e-3)
print("stream and measure_file agree to the mHz:", same)

# %%
# The figure: the measured steps with each reading's 2-sigma band; the flagged glitch.
fig, ax = plt.subplots(figsize=(7, 4))
offset_ghz = (out["frequency_hz"] - dev.center_hz) / 1e9
ax.plot(time_s, offset_ghz, ".", ms=2, label="measured")
bad = out["flags"] != 0
ax.plot(time_s[bad], offset_ghz[bad], "o", mfc="none", ms=10, color="C3", label="flagged")
ax.set_xlabel("time (s)")
ax.set_ylabel("frequency - centre (GHz)")
ax.legend()
inset = ax.inset_axes([0.08, 0.55, 0.35, 0.35])
window = slice(1000, 1040)
inset.errorbar(
    time_s[window],
    (out["frequency_hz"][window] - steps_hz[window]) / 1e6,
    yerr=2 * out["frequency_std_hz"][window] / 1e6,
    fmt=".",
    ms=3,
)
inset.set_title("error +- 2 std (MHz)", fontsize=8)
inset.tick_params(labelsize=7)
fig.tight_layout()

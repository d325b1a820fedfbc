"""
Cascade: wrong-order rate against noise, seen and predicted
===========================================================

A cascade of interferometers of decreasing FSR reads absolute frequency with no coarse
input: the coarsest stage's phase is unique over the band and each stage picks the fringe
order of the next. A wrong order is an error of a whole FSR, so every reading carries the
probability that some stage picked a wrong one
(:meth:`wavemeter.CascadeCalibrator.order_error_probability`).

Here :func:`wavemeter.design_cascade` designs the fewest stages that read the C band at a
wrong-order rate of 1e-3 per reading at a noise of 8e-7 W (two stages); the simulated
cascade is calibrated at that noise, then read at 1 to 10 times it. The wrong orders seen
(errors over half the finest FSR) follow the sum of the predicted probabilities, and
``ORDER_AMBIGUOUS`` flags them. ``benchmarks/cascade.py`` (``make cascade``) is the full
study with 1e6 readings per level.
"""

import warnings

import matplotlib.pyplot as plt
import numpy as np

import wavemeter as wm

BAND_HZ = (191.0e12, 195.4e12)
NOISE_W = 8e-7
design = wm.design_cascade(BAND_HZ, 50e9, noise_w=NOISE_W, wrong_order_rate=1e-3)
print(design)

# %%
# Simulate the design, calibrate it from one sweep over the band
fsrs_hz = tuple(design.fsrs_hz)
dev = wm.CascadeInterferometer.table1(fsrs_hz, ports=3, seed=2, center_hz=sum(BAND_HZ) / 2)
sweep_hz = np.linspace(*BAND_HZ, 6000)
sweep = dev.powers(sweep_hz, 1e-3, NOISE_W, rng=1)
with warnings.catch_warnings(record=True) as caught:  # what the fit says, cause by cause
    warnings.simplefilter("always")
    cal = wm.CascadeCalibrator(fsr_hz=fsrs_hz, max_order_error=1e-2).fit(sweep, sweep_hz)
for note in caught:
    print(f"warning [{note.message.cause}]: {str(note.message)[:120]}...")
for handover in cal.handovers_:
    print({key: handover[key] for key in ("from_stage", "to_stage", "ratio", "margin_std")})

# %%
# Read at 1 to 10 times the noise
rng = np.random.default_rng(3)
finest_fsr_hz = fsrs_hz[-1]
levels = (1, 2, 3, 5, 10)
seen, predicted, flagged = [], [], []
for factor in levels:
    test_hz = rng.uniform(*BAND_HZ, 10_000)
    test = dev.powers(test_hz, 1e-3, factor * NOISE_W, rng=rng)
    wrong = np.abs(cal.predict(test) - test_hz) > finest_fsr_hz / 2
    probability = cal.order_error_probability(test)
    ambiguous = (cal.flags(test) & wm.ReadingFlag.ORDER_AMBIGUOUS) != 0
    seen.append(wrong.sum())
    predicted.append(probability.sum())
    flagged.append((wrong & ambiguous).sum())
    print(
        f"{factor:2d}x noise: wrong orders {wrong.sum():5d} of {test_hz.size},"
        f" predicted {probability.sum():8.1f}, flagged {(wrong & ambiguous).sum()}"
    )

# %%
# The figure: wrong orders per reading against the noise, seen and predicted.
fig, ax = plt.subplots(figsize=(7, 4))
ax.loglog(levels, np.array(predicted) / 10_000, "k-", label="predicted (sum of probabilities)")
ax.loglog(levels, np.maximum(seen, 0.5) / 10_000, "o", label="seen (errors > FSR / 2)")
ax.axhline(1e-3, color="0.6", ls=":", label="design rate at 1x")
ax.set_xlabel("noise / design noise")
ax.set_ylabel("wrong orders per reading")
ax.set_title(f"{len(fsrs_hz)} stages: " + " / ".join(f"{f / 1e9:.4g} GHz" for f in fsrs_hz))
ax.legend()
fig.tight_layout()

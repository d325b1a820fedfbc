"""
A calibrator of your own
========================

A calibrator written outside the package: the learned map at a known delay (a chip whose
FSR is known from elsewhere, so no delay is searched). It implements only the minimal
interface of :doc:`/user-guide/custom-calibrator`: a tag, its settings, what it learns from
a checked sweep (``_learn``), the phase of readings (``_phase``) and what its file keeps
(``_state`` / ``_set_state``). Everything else comes with the contract: the fit's checks and
warnings, per-reading flags, ``readout`` and ``stream``, files, the summary and every
command of the command line.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import wavemeter as wm
from wavemeter.calibration import BaseCalibrator, SweepFitMixin
from wavemeter.cli import main
from wavemeter.model import cone_vectors, delay_phase_rad

# %%
# The calibrator
# --------------
# ``SweepFitMixin`` gives ``fit``: the sweep is checked, the design FSR compared with the
# sweep's own fringes, every port's fringe judged, then ``_learn`` runs, and the sweep is
# tested against the cone model (warnings with cause and remedy). ``_learn`` sets the
# learned attributes (names ending ``_``); the sweep's layout (``center_hz_``,
# ``n_ports_``...) is already set. Defining the class with a ``method`` tag registers it.


class KnownDelayCalibrator(SweepFitMixin, BaseCalibrator):
    """The learned map at the design FSR (Hz): no delay search."""

    method = "known_delay"

    def __init__(self, fsr_hz=50e9):
        self.fsr_hz = fsr_hz

    def _learn(self, sweep):
        phase_rad = delay_phase_rad(sweep.frequency_hz, self.center_hz_, 1.0 / self.fsr_hz)
        power = 1.0 if sweep.scale is None else sweep.scale
        objects = cone_vectors(phase_rad, power)  # (N, 3) cone vectors
        solution, *_ = np.linalg.lstsq(objects, sweep.powers_w, rcond=None)
        self.map_ = solution.T  # (n, 3), W
        self.fsr_hz_ = float(self.fsr_hz)

    def _phase(self, readings):
        objects = readings @ np.linalg.pinv(self.map_).T
        return np.arctan2(objects[:, 1], objects[:, 0])

    def _state(self):
        return {"map": self.map_.tolist()}

    def _set_state(self, state):
        self.map_ = np.asarray(state["map"], dtype=float)


# %%
# Fit and read
# ------------
# A simulated 3x3 meter whose true FSR is 0.2 % off the datasheet value: the known-delay
# calibration carries that error as a frequency-dependent bias, the learned calibration
# (which searches the delay) does not. The fit's checks judge the sweep against the cone
# model, not a method's shortcuts: the bias shows in the calibration's own RMS error on its
# sweep (``calibration_rms_hz_``, in every summary), as it does on the test readings.
dev = wm.Interferometer.table1(ports=3, seed=7)
f_hz = dev.sweep_hz(2001)
P = dev.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)
datasheet_fsr_hz = dev.true_fsr_hz * 1.002

known = KnownDelayCalibrator(fsr_hz=datasheet_fsr_hz).fit(P, f_hz)
learned = wm.Calibrator(fsr_hz=datasheet_fsr_hz).fit(P, f_hz)

rng = np.random.default_rng(2)
test_hz = dev.center_hz + (rng.random(4000) - 0.5) * 0.98 * dev.true_fsr_hz
test = dev.powers(test_hz, power_w=1e-3, noise_w=5e-7, rng=rng)
for cal in (known, learned):
    error_hz = cal.predict(test) - test_hz
    flagged = np.count_nonzero(cal.flags(test))
    print(
        f"{cal.method_label:12s} on its sweep {cal.calibration_rms_hz_ / 1e6:6.2f} MHz RMS, "
        f"on the test {np.sqrt(np.mean(error_hz**2)) / 1e6:6.2f} MHz RMS, "
        f"{flagged} of {test.shape[0]} readings flagged"
    )

# %%
# Files and the command line
# --------------------------
# The calibration file keeps the tag, the settings, the common learned attributes and
# ``_state``; ``wm.load_calibration`` finds the class by its tag (here registered by the
# class statement above; a package registers it through an entry point). The command line
# offers the tag as a ``--method`` choice, in this process as in any other that imports the
# class.
folder = Path(tempfile.mkdtemp())
known.save(folder / "chip.wmcal.json")
loaded = wm.load_calibration(folder / "chip.wmcal.json")
print("loaded predicts the same:", np.array_equal(loaded.predict(test), known.predict(test)))

wm.io.write_table(
    folder / "sweep.csv", {"frequency_hz": f_hz, **{f"p{k + 1}_w": P[:, k] for k in range(3)}}
)
code = main(
    [
        "calibrate",
        str(folder / "sweep.csv"),
        "-o",
        str(folder / "cli.wmcal.json"),
        "--method",
        "known_delay",
        "--fsr",
        f"{datasheet_fsr_hz}Hz",
    ]
)
print("wavemeter calibrate --method known_delay: exit code", code)

# %%
# The bias a wrong delay leaves
# -----------------------------
# The known-delay calibration's error grows linearly away from the centre of the sweep: the
# phase it assigns runs at the datasheet delay, the chip's at its own.
fig, ax = plt.subplots(figsize=(7, 3.5))
for cal in (known, learned):
    ax.plot(
        (test_hz - dev.center_hz) / 1e9,
        (cal.predict(test) - test_hz) / 1e6,
        ".",
        ms=1.5,
        label=cal.method_label,
    )
ax.set_xlabel("frequency - centre (GHz)")
ax.set_ylabel("error (MHz)")
ax.legend(markerscale=6)
fig.tight_layout()

"""How the files in this folder were written: by wavemeter 0.7.1 (commit 03d2f4d), before
calibration files kept the ``off_model`` record, with the flags that version gives.

Run from the repository root at that commit (``python tests/data/offmodel-0.7.1/make_files.py``);
run with a later version it writes files with the record, which the test does not want.
Detector compression of 5 % at the sweep's largest reading gives the fit a model error
(``other_misfit``), so the detector-noise test flags most good readings.
"""

import json
import warnings
from pathlib import Path

import numpy as np

import wavemeter as wm

OUT = Path("tests/data/offmodel-0.7.1")
GAMMA = 0.05  # detector compression at the sweep's largest reading


def compressed(powers, peak):
    return powers - GAMMA * powers**2 / peak


warnings.simplefilter("ignore")
rng = np.random.default_rng(20261128)
dev = wm.Interferometer.table1(ports=3, seed=1)
expected = {"gamma": GAMMA}
for name, span in (("learned", 1.0), ("wideband", 6.0)):
    f = dev.sweep_hz(2001 if span == 1 else 6001, span_fsr=span)
    sweep = dev.powers(f, power_w=1e-3, noise_w=5e-7, rng=rng)
    peak = float(sweep.max())
    cal = wm.Calibrator(fsr_hz=50e9) if name == "learned" else wm.WidebandCalibrator(fsr_hz=50e9)
    cal.fit(compressed(sweep, peak), f)
    cal.save(OUT / f"{name}.wmcal.json")
    ft = rng.uniform(f.min(), f.max(), 80)
    readings = compressed(dev.powers(ft, power_w=1e-3, noise_w=5e-7, rng=rng), peak)
    ports = rng.integers(0, 3, 20)
    readings[np.arange(60, 80), ports] += rng.choice([-1, 1], 20) * 100 * 5e-7
    coarse = ft + rng.normal(0, 1e9, ft.size)
    kwargs = {"coarse_hz": coarse} if cal.requires else {}
    loaded = wm.load_calibration(OUT / f"{name}.wmcal.json")
    flags = loaded.flags(readings, **kwargs)
    assert np.array_equal(flags, cal.flags(readings, **kwargs))
    stream = [r.flags for r in loaded.stream(readings, **kwargs)]
    assert list(flags) == stream
    expected[name] = {
        "readings_w": readings.tolist(),
        "coarse_hz": coarse.tolist(),
        "flags": [int(v) for v in flags],
    }
    print(
        name,
        "OFF_MODEL",
        np.count_nonzero(flags & 1),
        "of",
        flags.size,
        "any",
        np.count_nonzero(flags),
    )
(OUT / "expected.json").write_text(json.dumps(expected, indent=1) + "\n")

"""How the files in this folder were written: by wavemeter 0.7.1 at commit 0ae97fd (the
first round of issue 29's OFF_MODEL), whose ``off_model`` record has no ``residual``: its
test is the detector noise's scaled to the sweep's median distance. With the flags that
version gives.

Run from the repository root with that commit's package on the path, e.g.
``git archive 0ae97fd src | tar -x -C /tmp/round1`` then
``PYTHONPATH=/tmp/round1/src python tests/data/offmodel-round1/make_files.py``; run with a
later version it writes files with the residual, which the test does not want. Detector
compression of 5 % at the sweep's largest reading gives the fit a model error
(``other_misfit``); 20 of the 80 readings carry a glitch of 100 noise standard deviations.
"""

import json
import warnings
from pathlib import Path

import numpy as np

import wavemeter as wm

OUT = Path("tests/data/offmodel-round1")
GAMMA = 0.05  # detector compression at the sweep's largest reading


def compressed(powers, peak):
    return powers - GAMMA * powers**2 / peak


warnings.simplefilter("ignore")
rng = np.random.default_rng(20261129)
dev = wm.Interferometer.table1(ports=3, seed=1)
expected = {"gamma": GAMMA, "commit": "0ae97fd"}
for name, span in (("learned", 1.0), ("wideband", 6.0)):
    f = dev.sweep_hz(2001 if span == 1 else 6001, span_fsr=span)
    sweep = dev.powers(f, power_w=1e-3, noise_w=5e-7, rng=rng)
    peak = float(sweep.max())
    cal = wm.Calibrator(fsr_hz=50e9) if name == "learned" else wm.WidebandCalibrator(fsr_hz=50e9)
    cal.fit(compressed(sweep, peak), f)
    assert (
        cal.off_model_basis_.model_error and "residual" not in cal._off_model_state()["off_model"]
    )
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
    print(name, "OFF_MODEL", np.count_nonzero(flags & 1), "of", flags.size)
(OUT / "expected.json").write_text(json.dumps(expected, indent=1) + "\n")

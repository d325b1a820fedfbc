"""A cascade whose coarsest stage's fringe covers nearly the whole band (issue 29).

The issue's cascade with 4 ports per stage (the benchmark's device: 5 THz / 500 GHz / 50 GHz
from ``SeedSequence([0, 4, 0])``, silicon-nitride spectral slopes) draws a coarsest stage of
4.446 THz over the 4.4 THz band: 0.99 of its fringe. Its map turns the fringe by more
between the band's middle and ends than the band leaves of the fringe, so a reading near an
end read from the middle's map had a twin at the other end that its map read as itself:
the sweep's readings at the ends were read 4.4 THz off (stage 1's z-scores spread 140 on a
600-reading sweep), and readings near the ends took a wrong order with a predicted rate of
nearly none. Of a reading and its twin the cascade now takes the one nearer its map's
cone, and refuses a coarsest stage that reads its sweep a fringe away more often than it
predicts.
"""

from __future__ import annotations

import functools
import warnings

import numpy as np
import pytest
from scipy import stats

import wavemeter as wm

FSRS_HZ = (5e12, 500e9, 50e9)
BAND_HZ = (191.0e12, 195.4e12)
POWER_W = 1e-3
NOISE_W = 5e-7
SWEEP_READINGS = 600
#: the p-value of every check here, as the cascade's own (``HANDOVER_P_VALUE``)
P_VALUE = 1e-6
#: readings within this distance of each end of the band (Hz)
END_HZ = 40e9


@functools.cache
def device() -> wm.CascadeInterferometer:
    rng = np.random.default_rng(np.random.SeedSequence([0, 4, 0]))
    return wm.CascadeInterferometer.table1(FSRS_HZ, 4, seed=rng, center_hz=193.2e12, spectral="sin")


def sweep() -> tuple[np.ndarray, np.ndarray]:
    """One sweep evenly over the band at the design noise, and its frequencies (Hz)."""
    sweep_hz = np.linspace(*BAND_HZ, SWEEP_READINGS)
    return device().powers(sweep_hz, POWER_W, NOISE_W, rng=0), sweep_hz


@functools.cache
def calibrated():
    """The cascade fitted on the sweep, and the warnings it raised."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", wm.CalibrationWarning)
        cal = wm.CascadeCalibrator(fsr_hz=FSRS_HZ).fit(*sweep())
    return cal, [entry.message for entry in caught]


def end_readings(count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``count`` readings at the design noise within ``END_HZ`` of either end of the band,
    and their frequencies (Hz)."""
    rng = np.random.default_rng(seed)
    low = rng.uniform(BAND_HZ[0], BAND_HZ[0] + END_HZ, count // 2)
    high = rng.uniform(BAND_HZ[1] - END_HZ, BAND_HZ[1], count - count // 2)
    frequency_hz = np.concatenate([low, high])
    return device().powers(frequency_hz, POWER_W, NOISE_W, rng=rng), frequency_hz


def test_the_device_covers_nearly_its_whole_coarsest_fringe():
    """The case is what this module says: the band covers 0.99 of stage 1's fringe, and
    the fit finds that FSR (not refused, as the band is narrower)."""
    cal, _ = calibrated()
    true_fsr_hz = device().true_fsrs_hz[0]
    assert 0.98 < (BAND_HZ[1] - BAND_HZ[0]) / true_fsr_hz < 1.0
    # the stage's FSR within 5 of its standard errors
    fsr = cal.summary().values["stage_1_fsr_hz"]
    assert abs(fsr.value - true_fsr_hz) < 5 * fsr.stderr, (fsr.value, fsr.stderr)


def test_the_coarsest_stage_reads_its_sweep_within_its_uncertainty():
    """Every stage's z-scores on its own sweep spread as the noise allows: their variance
    below the chi-square quantile at ``P_VALUE`` (stage 1's spread 140 before: its band's
    ends read at the other end); no wrong order on the sweep, no warning."""
    cal, notes = calibrated()
    assert not notes, [str(note) for note in notes]
    limit = np.sqrt(stats.chi2.isf(P_VALUE, SWEEP_READINGS) / SWEEP_READINGS)
    spreads = [stage["z_std"] for stage in cal.diagnostics_["cascade"]["stages"]]
    assert max(spreads) < limit, spreads
    assert all(record["wrong_on_sweep"] == 0 for record in cal.handovers_)


def test_readings_at_the_band_ends_take_the_right_order_or_say_so():
    """At the band's ends every reading's order is right unless flagged ORDER_AMBIGUOUS,
    and the wrong orders are as many as their probabilities predict (Poisson)."""
    cal, _ = calibrated()
    powers, frequency_hz = end_readings(400, seed=5)
    readout = cal.readout(powers)
    wrong = np.abs(readout.frequency_hz - frequency_hz) > 0.5 * cal.fsr_hz_at(frequency_hz)
    ambiguous = (readout.flags & wm.ReadingFlag.ORDER_AMBIGUOUS) != 0
    assert not np.any(wrong & ~ambiguous), np.flatnonzero(wrong & ~ambiguous)
    predicted = float(np.sum(readout.extras["order_error_probability"]))
    seen = int(np.count_nonzero(wrong))
    assert seen == 0 or stats.poisson.sf(seen - 1, predicted) >= P_VALUE, (seen, predicted)


def test_a_stream_takes_the_twin_a_batch_takes():
    """A stream reads the band's ends as a batch does (one reading at a time, the twin
    weighed the same way)."""
    cal, _ = calibrated()
    powers, _ = end_readings(19, seed=6)
    batch = cal.readout(powers)
    streamed = list(cal.stream(powers))
    np.testing.assert_allclose(
        [reading.frequency_hz for reading in streamed], batch.frequency_hz, rtol=1e-12
    )
    np.testing.assert_array_equal([reading.flags for reading in streamed], batch.flags)


def test_a_coarsest_stage_that_reads_its_sweep_a_fringe_away_is_refused():
    """Sweep readings recorded at one end of the band but taken at the other are read a
    fringe away by stage 1, which its uncertainties do not predict: its order probabilities
    do not hold, and the fit is refused, naming the stage, the cause and the remedy."""
    powers, sweep_hz = sweep()
    swapped = powers.copy()
    swapped[-10:] = device().powers(sweep_hz[:10], POWER_W, NOISE_W, rng=7)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        with pytest.raises(wm.InputError, match="a whole fringe away") as caught:
            wm.CascadeCalibrator(fsr_hz=FSRS_HZ).fit(swapped, sweep_hz)
    assert caught.value.parameter == "fsr_hz"
    assert str(caught.value).startswith("stage 1 (5 THz) read 10 of the 600 sweep readings")
    assert "narrower than that FSR" in str(caught.value)

"""What a wide-band calibration states about itself: its phase coefficients and their
standard errors, the ports' noise, the orders marked chosen (issue 29, item 9).

The truth of the phase coefficients is the simulation's fringe phase (``tests/_fringe.py``):
the device's phase ``t`` plus the mean phase of the ports' fringe amplitudes in the true
map, weighted by their fringe power at the centre. A coefficient lies within 4 of its
standard errors of the truth (a Gaussian error exceeds that with probability 6e-5); an
estimated standard deviation over ``d`` degrees of freedom has a relative standard error
``1 / sqrt(2 d)``.
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.simulation import Scenario

from ._fringe import true_fringe_coefficients_s

#: the user guide's example (24 FSRs of the SiN preset with 25x its dispersion), with half
#: its samples
GUIDE = {"spectral": "sin", "dispersion_s2": 1e-26, "span_fsr": 24.0, "samples": 4800}
NOISE_W = 5e-7
MAX_Z = 4.0


def sweep(seed: int, **fields) -> tuple[Scenario, np.ndarray, np.ndarray]:
    scenario = Scenario(seed=seed, **{**GUIDE, **fields})
    table, _ = scenario.tables()
    frequency_hz = table.pop("frequency_hz")
    return scenario, np.column_stack(list(table.values())), frequency_hz


def calibrated(seed: int, **settings):
    scenario, powers_w, frequency_hz = sweep(seed, **settings.pop("scenario", {}))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wm.CalibrationWarning)
        calibration = wm.WidebandCalibrator(**settings).fit(powers_w, frequency_hz)
    return scenario.device, calibration


def truth_of(device, calibration) -> np.ndarray:
    return true_fringe_coefficients_s(
        device, calibration.center_hz_, calibration.half_span_hz_, calibration.phase_order_
    )


@pytest.fixture(scope="module")
def guide():
    """The user guide's sweep, seed 2, orders chosen."""
    return calibrated(2)


def test_noiseless_sweep_gives_the_true_fringe_phase_whatever_the_map_absorbs():
    """The simulated map is cubic in frequency: orders (2, 3) hold the device exactly, and
    its fringe phase comes out to rounding, though a map of order 3 leaves the model phase
    ``t`` alone told only weakly from it."""
    device, calibration = calibrated(
        2, phase_order=2, map_order=3, scenario={"noise_w": 0.0, "samples": 2400}
    )
    truth = truth_of(device, calibration)
    np.testing.assert_allclose(calibration.phase_coefficients_, truth, rtol=1e-7)
    assert calibration.delay_s_ == calibration.phase_coefficients_[0]
    assert calibration.fsr_hz_ == pytest.approx(1.0 / truth[0], rel=1e-9)
    assert calibration.fsr_hz_at(calibration.center_hz_) == pytest.approx(
        calibration.fsr_hz_, rel=1e-12
    )


def test_the_simulators_fringe_fsr_is_the_fringe_phase_truth(guide):
    """``Interferometer.fringe_fsr_hz`` (a central difference of the true map's fringe
    phase, what ``simulate`` prints) is the truth of ``fsr_hz_`` (``tests/_fringe.py``, a
    Chebyshev fit): the two agree to the difference's error, (1 GHz / 1 THz)^2 of the
    couplers' share, itself below 1e-4 of the FSR; the calibration lies within its
    standard errors of it."""
    device, calibration = guide
    truth_hz = 1.0 / truth_of(device, calibration)[0]
    fringe_hz = device.fringe_fsr_hz(calibration.center_hz_)[0]
    assert fringe_hz == pytest.approx(truth_hz, rel=1e-10)
    assert abs(fringe_hz / device.local_fsr_hz(np.array([calibration.center_hz_]))[0] - 1) > 1e-7
    fsr = calibration.summary().values["fsr_hz"]
    assert abs(fsr.value - fringe_hz) < MAX_Z * fsr.stderr


def test_phase_coefficients_lie_within_their_standard_errors_of_the_truth(guide):
    device, calibration = guide
    record = calibration.diagnostics_["wideband"]
    std = np.asarray(record["phase_coefficients_std_s"])
    truth = truth_of(device, calibration)
    assert np.all(np.abs(calibration.phase_coefficients_ - truth) < MAX_Z * std)
    values = calibration.summary().values
    assert values["fsr_hz"].value == calibration.fsr_hz_ == 1.0 / calibration.delay_s_
    assert values["fsr_hz"].stderr == pytest.approx(calibration.fsr_hz_**2 * std[0], rel=1e-12)
    assert values["delay_s"].stderr == std[0]
    if calibration.phase_order_ >= 2:
        assert values["phase_coefficient_2_s2"].stderr == std[1]


def test_port_lines_state_the_noise_under_the_band_model(guide):
    """Each port's noise is its residual under the band model: the simulated detector
    noise, as the fit's noise estimate says (not the misfit of one map over the band)."""
    _, calibration = guide
    dof = calibration.n_samples_ - calibration.n_parameters_
    ports = calibration.diagnostics_["ports"]
    for port in ports:
        assert port["status"] == "ok"
        assert abs(port["noise_std_w"] / NOISE_W - 1.0) < MAX_Z / math.sqrt(2 * dof)
    pooled = math.sqrt(np.mean([port["noise_std_w"] ** 2 for port in ports]))
    # the pooled estimate counts the shared phase coefficients once, each port all of them
    assert pooled == pytest.approx(calibration.noise_std_w_, rel=1e-3)


def test_a_dead_port_is_found_under_the_band_model():
    """A port that records noise only has no fringe under the band model either."""
    _, powers_w, frequency_hz = sweep(2, ports=4)
    powers_w[:, 2] = np.random.default_rng(7).normal(1e-4, NOISE_W, frequency_hz.size)
    with pytest.warns(wm.CalibrationWarning, match="no usable fringe"):
        calibration = wm.WidebandCalibrator().fit(powers_w, frequency_hz)
    status = [port["status"] for port in calibration.diagnostics_["ports"]]
    assert status == ["ok", "ok", "dead", "ok"]


def _chosen_rows(calibration) -> list[tuple]:
    table = next(t for t in calibration.summary().tables if t.name == "orders")
    return [row[:2] for row in table.rows if row[4] == "chosen"]


def test_the_orders_raised_after_cross_validation_are_the_ones_marked_chosen():
    """With the phase order fixed at 1, cross-validation stops at a map order the sweep's F
    test then raises: the raised orders are scored and marked, not the ones it stopped at."""
    _, calibration = calibrated(2, phase_order=1, scenario={"samples": 9600})
    record = calibration.diagnostics_["wideband"]["orders"]
    assert "raised" in record["reason"]
    fitted = (calibration.phase_order_, calibration.map_order_)
    chosen = [c for c in record["candidates"] if c["chosen"]]
    assert [(c["phase_order"], c["map_order"]) for c in chosen] == [fitted]
    assert chosen[0]["cv_rms_hz"] > 0
    assert _chosen_rows(calibration) == [fitted]


def test_the_orders_chosen_by_cross_validation_are_marked(guide):
    _, calibration = guide
    assert _chosen_rows(calibration) == [(calibration.phase_order_, calibration.map_order_)]


def test_files_written_before_the_fringe_phase_keep_their_model_phase(guide, tmp_path):
    """A calibration file without ``phase_definition`` (written before) reports what it
    did then: the model phase's coefficients; it reads the same frequencies."""
    _, calibration = guide
    path = tmp_path / "band.json"
    wm.save_calibration(calibration, path)
    document = json.loads(path.read_text())
    assert document["state"]["phase_definition"] == "fringe"
    del document["state"]["phase_definition"]
    half = calibration.half_span_hz_
    document["fsr_hz"] = 2.0 * np.pi * half / calibration.phase_coefficients_rad_[0]
    path.write_text(json.dumps(document))
    old = wm.load_calibration(path)
    assert old.phase_definition_ == "model"
    assert old.fsr_hz_ == document["fsr_hz"]
    assert old.phase_coefficients_[1] == pytest.approx(
        calibration.phase_coefficients_rad_[1] * 2.0 / (2.0 * np.pi * half) ** 2, rel=1e-12
    )
    _, powers_w, frequency_hz = sweep(2)
    rows = slice(0, None, 97)
    np.testing.assert_array_equal(
        old.predict(powers_w[rows], coarse_hz=frequency_hz[rows]),
        calibration.predict(powers_w[rows], coarse_hz=frequency_hz[rows]),
    )


@pytest.mark.slow
def test_the_standard_errors_cover_the_truth_across_seeds():
    """Over 30 seeds of the user guide's sweep (device, slopes and noise drawn from the
    seed) ``z = (fit - truth) / std`` of the delay and the dispersion has a standard
    deviation of 1 (within 3.5 of its standard errors 1 / sqrt(2 x 29)) and 95 % within
    1.96 (at least 25 of 30: 3.5 binomial standard deviations below 28.5)."""
    z = []
    for seed in range(1, 31):
        device, calibration = calibrated(seed, phase_order=2)
        std = np.asarray(calibration.diagnostics_["wideband"]["phase_coefficients_std_s"])
        z.append((calibration.phase_coefficients_ - truth_of(device, calibration)) / std)
    z = np.array(z)
    spread = 3.5 / math.sqrt(2 * (len(z) - 1))
    assert np.all(np.abs(z.std(axis=0, ddof=1) - 1.0) < spread)
    assert np.all(np.count_nonzero(np.abs(z) < 1.959964, axis=0) >= 25)

"""design_cascade: the fewest ideal stages that read a band at a requested wrong-order rate.

The derivation is checked against a simulation of ideal Gaussian stage errors decoded as a
cascade does (the coarsest stage wrapped into its range, each finer stage's order picked
from the stage before); the choice of stages and FSRs against its limits. The search's
closed-form rates are checked in ``test_cascade_search.py``.
"""

from __future__ import annotations

import functools
import json
import math

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.model.cascade_design import MAX_STAGES
from wavemeter.model.orders import (
    any_error_probability,
    handover_error_rate,
)

from .helpers import band_average_edge_rate

#: the issue's example: the C band, 50 GHz finest FSR, 0.5 uW noise, 1 mW, 3 ports
BAND_HZ = (191.0e12, 195.4e12)
FINEST_FSR_HZ = 50e9
#: detector noise (W) that pushes the best C-band designs to a rate of about 1e-2
PUSHED_NOISE_W = 1.6e-5
#: binomial standard errors a measured rate may lie from its prediction
ALLOWED_STANDARD_ERRORS = 5.0


#: the derivation's items 1-7: ideal stages with exact FSRs (item 8 relaxes both)
ideal_design = functools.partial(wm.design_cascade, noise_factor=1.0, fsr_tolerance=0.0)


def _binomial_close(count: int, trials: int, predicted: float) -> None:
    standard_error = math.sqrt(predicted * (1.0 - predicted) / trials)
    assert abs(count / trials - predicted) < ALLOWED_STANDARD_ERRORS * standard_error, (
        count / trials,
        predicted,
    )


# ---------------------------------------------------------------------------- the derivation


def _decode(design, trials: int, rng):
    """Ideal Gaussian stage errors for truths uniform over the band, decoded as a cascade:
    the coarsest estimate wrapped into its range centred on the band, each finer stage's
    order the one nearest the stage before. Returns the wrap events, the hand-over events
    (wrong order given the stage before was right) and the readings wrong at the end."""
    low, high = design.band_hz
    middle = (low + high) / 2.0
    fsrs = design.fsrs_hz
    truth = rng.uniform(low, high, trials)
    errors = [rng.normal(0.0, std, trials) for std in design.stage_std_hz]
    estimate = truth + errors[0]
    wrapped = np.abs(estimate - middle) > fsrs[0] / 2.0
    estimate = middle + np.mod(estimate - middle + fsrs[0] / 2.0, fsrs[0]) - fsrs[0] / 2.0
    handovers = []
    for stage in range(1, len(fsrs)):
        handovers.append(np.abs(errors[stage - 1] - errors[stage]) > fsrs[stage] / 2.0)
        within = np.mod(truth + errors[stage], fsrs[stage])
        estimate = within + np.round((estimate - within) / fsrs[stage]) * fsrs[stage]
    wrong = np.abs(estimate - truth) > fsrs[-1] / 2.0
    return wrapped, handovers, wrong


def test_simulated_wrong_orders_match_the_predicted_rates():
    design = ideal_design(BAND_HZ, FINEST_FSR_HZ, noise_w=PUSHED_NOISE_W, wrong_order_rate=0.05)
    assert design.stages >= 3 and 3e-3 < design.wrong_order_rate < 5e-2  # many errors
    trials = 1_000_000
    wrapped, handovers, wrong = _decode(design, trials, np.random.default_rng(7))
    _binomial_close(int(wrapped.sum()), trials, design.edge_rate)
    for events, rate in zip(handovers, design.handover_rates, strict=True):
        _binomial_close(int(events.sum()), trials, rate)
    _binomial_close(int(wrong.sum()), trials, design.wrong_order_rate)


def test_stage_stds_margins_and_rates_follow_the_ideal_bound():
    design = ideal_design(BAND_HZ, FINEST_FSR_HZ, noise_w=PUSHED_NOISE_W, wrong_order_rate=0.05)
    stage_power_w = design.power_w / design.stages
    expected = [
        wm.crlb_ideal_frequency_std(design.ports, stage_power_w, design.noise_w, fsr)
        for fsr in design.fsrs_hz
    ]
    np.testing.assert_allclose(design.stage_std_hz, expected, rtol=1e-12)
    stds = np.array(design.stage_std_hz)
    residual = np.hypot(stds[:-1], stds[1:])
    fine = np.array(design.fsrs_hz[1:])
    np.testing.assert_allclose(design.handover_margins, fine / 2.0 / residual, rtol=1e-12)
    np.testing.assert_allclose(design.handover_rates, handover_error_rate(fine, residual))
    assert design.edge_margin == pytest.approx(
        (design.fsrs_hz[0] - design.band_width_hz) / (2.0 * stds[0]), rel=1e-12
    )
    total = any_error_probability([design.edge_rate, *design.handover_rates])
    assert design.wrong_order_rate == pytest.approx(float(total), rel=1e-12)


def _brute_force_rate(design, coarsest_fsr_hz: float) -> float:
    """The total rate of ``design``'s stage count with another coarsest FSR, from the
    public functions and quadrature."""
    stages = design.stages
    fsrs = coarsest_fsr_hz * (FINEST_FSR_HZ / coarsest_fsr_hz) ** (np.arange(stages) / (stages - 1))
    stds = np.array(
        [
            wm.crlb_ideal_frequency_std(3, design.power_w / stages, design.noise_w, fsr)
            for fsr in fsrs
        ]
    )
    handovers = handover_error_rate(fsrs[1:], np.hypot(stds[:-1], stds[1:]))
    edge = band_average_edge_rate(fsrs[0], stds[0], design.band_width_hz)
    return float(any_error_probability([edge, *handovers]))


@pytest.mark.slow
def test_the_coarsest_fsr_minimises_the_rate():
    design = ideal_design(BAND_HZ, FINEST_FSR_HZ, noise_w=PUSHED_NOISE_W, wrong_order_rate=0.05)
    width = design.band_width_hz
    grid = width * (1.0 + np.geomspace(1e-3, 10.0, 400))
    best_on_grid = min(_brute_force_rate(design, fsr) for fsr in grid)
    assert design.wrong_order_rate <= best_on_grid * (1.0 + 1e-6)
    assert _brute_force_rate(design, design.fsrs_hz[0]) == pytest.approx(
        design.wrong_order_rate, rel=1e-6
    )


# ---------------------------------------------------------------------------- the choice
@pytest.mark.parametrize(
    ("noise_w", "rate"),
    [(5e-7, 1e-9), (5e-6, 1e-9), (5e-6, 1e-15), (PUSHED_NOISE_W, 0.05), (2e-6, 1e-30)],
)
def test_fewest_stages_that_meet_the_rate(noise_w, rate):
    design = ideal_design(BAND_HZ, FINEST_FSR_HZ, noise_w=noise_w, wrong_order_rate=rate)
    assert design.meets_rate and design.wrong_order_rate <= rate
    assert design.fsrs_hz[-1] == FINEST_FSR_HZ  # exactly
    assert design.fsrs_hz[0] > design.band_width_hz
    assert all(a > b for a, b in zip(design.fsrs_hz, design.fsrs_hz[1:], strict=False))
    np.testing.assert_allclose(design.ratios, design.ratios[0], rtol=1e-9)
    np.testing.assert_allclose(
        design.ratios, np.array(design.fsrs_hz[:-1]) / np.array(design.fsrs_hz[1:]), rtol=1e-12
    )
    np.testing.assert_allclose(design.handover_margins, design.handover_margins[0], rtol=1e-9)
    if design.stages > 2:  # K = 1 cannot cover this band, so K = 2 is the floor here
        fewer = ideal_design(
            BAND_HZ,
            FINEST_FSR_HZ,
            noise_w=noise_w,
            wrong_order_rate=rate,
            stages=design.stages - 1,
        )
        assert fewer.wrong_order_rate > rate and not fewer.meets_rate
    else:
        with pytest.raises(wm.InputError):  # the finest stage alone cannot cover the band
            ideal_design(BAND_HZ, FINEST_FSR_HZ, noise_w=noise_w, stages=1)


def test_issue_example_meets_its_rate_with_the_fewest_stages():
    design = ideal_design(
        BAND_HZ, FINEST_FSR_HZ, ports=3, power_w=1e-3, noise_w=5e-7, wrong_order_rate=1e-9
    )
    assert design.meets_rate and design.fsrs_hz[-1] == FINEST_FSR_HZ
    with pytest.raises(wm.InputError) as raised:  # 50 GHz alone does not cover the band
        ideal_design(BAND_HZ, FINEST_FSR_HZ, stages=design.stages - 1)
    assert raised.value.parameter == "stages"


def test_a_finest_fsr_wider_than_the_band_is_one_stage():
    design = ideal_design((193.0e12, 193.04e12), FINEST_FSR_HZ, noise_w=5e-7)
    assert design.fsrs_hz == (FINEST_FSR_HZ,) and design.handover_margins == ()
    assert design.wrong_order_rate == design.edge_rate <= 1e-9


@pytest.mark.slow
def test_more_noise_never_needs_fewer_stages():
    counts = []
    for noise_w in np.geomspace(1e-7, 1e-4, 16):
        try:
            counts.append(ideal_design(BAND_HZ, FINEST_FSR_HZ, noise_w=noise_w).stages)
        except wm.InputError:
            counts.append(MAX_STAGES + 1)
    assert counts == sorted(counts) and counts[0] < counts[-1]


def test_a_band_width_gives_the_design_of_the_band():
    by_edges = ideal_design(BAND_HZ, FINEST_FSR_HZ, noise_w=5e-6)
    by_width = ideal_design(BAND_HZ[1] - BAND_HZ[0], FINEST_FSR_HZ, noise_w=5e-6)
    assert by_width.band_hz is None and by_edges.band_hz == BAND_HZ
    np.testing.assert_allclose(by_width.fsrs_hz, by_edges.fsrs_hz, rtol=1e-12)


def test_the_design_as_json_and_as_a_table():
    design = ideal_design(BAND_HZ, FINEST_FSR_HZ, noise_w=5e-6)
    values = json.loads(json.dumps(design.to_dict()))
    assert values["fsrs_hz"] == list(design.fsrs_hz)
    assert values["stages"] == design.stages and values["meets_rate"] is True
    assert values["stage_power_w"] == pytest.approx(design.power_w / design.stages)
    lines = str(design).splitlines()
    assert lines[0].split()[:3] == ["stage", "FSR", "GHz"]
    assert [line.split()[0] for line in lines[1 : 1 + design.stages]] == [
        str(k + 1) for k in range(design.stages)
    ]
    assert "predicted" in lines[-1]


def test_real_stages_are_designed_for_their_noise_and_fsr_error():
    """Item 8: the stage stds are ``noise_factor`` times the ideal ones, and each rate is
    that of its worst FSRs within the tolerance, by Monte Carlo on Gaussian errors."""
    factor, tolerance = 2.0, 0.1
    design = wm.design_cascade(
        BAND_HZ,
        FINEST_FSR_HZ,
        noise_w=PUSHED_NOISE_W / 2,
        wrong_order_rate=0.05,
        noise_factor=factor,
        fsr_tolerance=tolerance,
    )
    assert (design.noise_factor, design.fsr_tolerance) == (factor, tolerance)
    stage_power_w = design.power_w / design.stages
    ideal = [
        wm.crlb_ideal_frequency_std(design.ports, stage_power_w, design.noise_w, fsr)
        for fsr in design.fsrs_hz
    ]
    np.testing.assert_allclose(design.stage_std_hz, factor * np.array(ideal), rtol=1e-12)
    # the coarsest stage's range stays wider than the band at its lowest FSR
    assert design.fsrs_hz[0] * (1 - tolerance) > design.band_width_hz
    rng = np.random.default_rng(8)
    trials = 1_000_000
    stds = design.stage_std_hz
    for index, rate in enumerate(design.handover_rates):
        fine_fsr = design.fsrs_hz[index + 1] * (1 - tolerance)
        residual = rng.normal(0.0, stds[index] * (1 + tolerance), trials) - rng.normal(
            0.0, stds[index + 1] * (1 - tolerance), trials
        )
        _binomial_close(int(np.count_nonzero(np.abs(residual) > fine_fsr / 2)), trials, rate)
    low, high = BAND_HZ
    truth = rng.uniform(low, high, trials)
    estimate = truth + rng.normal(0.0, stds[0] * (1 - tolerance), trials)
    wrapped = np.abs(estimate - (low + high) / 2) > design.fsrs_hz[0] * (1 - tolerance) / 2
    _binomial_close(int(np.count_nonzero(wrapped)), trials, design.edge_rate)


def test_the_issue_example_with_real_stages_is_the_issue_cascade():
    """Allowing for Table 1 stages (2x the ideal noise, 10 % FSR error) the example needs
    three stages, about 5 THz / 500 GHz / 50 GHz as the issue has them."""
    design = wm.design_cascade(BAND_HZ, FINEST_FSR_HZ, noise_w=5e-7, power_w=1e-3)
    assert design.stages == 3 and design.meets_rate
    assert 4.5e12 < design.fsrs_hz[0] < 6e12 and 4e11 < design.fsrs_hz[1] < 6e11
    assert ideal_design(BAND_HZ, FINEST_FSR_HZ, noise_w=5e-7).stages == 2


def test_public_names():
    assert wm.design_cascade is wm.model.design_cascade
    assert isinstance(wm.design_cascade(BAND_HZ, FINEST_FSR_HZ), wm.CascadeDesign)
    assert {"design_cascade", "CascadeDesign"} <= set(wm.__all__)


# ---------------------------------------------------------------------------- refusals
@pytest.mark.parametrize(
    ("arguments", "parameter"),
    [
        ({"band_hz": (195.4e12, 191e12)}, "band_hz"),
        ({"band_hz": (191e12, math.nan)}, "band_hz"),
        ({"band_hz": "C band"}, "band_hz"),
        ({"band_hz": -4.4e12}, "band_hz"),
        ({"finest_fsr_hz": 0.0}, "finest_fsr_hz"),
        ({"finest_fsr_hz": math.inf}, "finest_fsr_hz"),
        ({"ports": 2}, "ports"),
        ({"ports": 3.0}, "ports"),
        ({"ports": True}, "ports"),
        ({"power_w": -1e-3}, "power_w"),
        ({"noise_w": 0.0}, "noise_w"),
        ({"wrong_order_rate": 0.0}, "wrong_order_rate"),
        ({"wrong_order_rate": 1.0}, "wrong_order_rate"),
        ({"stages": 0}, "stages"),
        ({"stages": MAX_STAGES + 1}, "stages"),
        ({"noise_factor": 0.5}, "noise_factor"),
        ({"noise_factor": math.nan}, "noise_factor"),
        ({"fsr_tolerance": 1.0}, "fsr_tolerance"),
        ({"fsr_tolerance": -0.1}, "fsr_tolerance"),
    ],
)
def test_bad_values_are_refused_naming_the_parameter(arguments, parameter):
    values = {"band_hz": BAND_HZ, "finest_fsr_hz": FINEST_FSR_HZ, **arguments}
    band, finest = values.pop("band_hz"), values.pop("finest_fsr_hz")
    with pytest.raises(wm.InputError) as raised:
        wm.design_cascade(band, finest, **values)
    assert raised.value.parameter == parameter and parameter in str(raised.value)


def test_an_impossible_rate_is_refused_with_the_best_reached_and_what_helps():
    with pytest.raises(wm.InputError) as raised:
        wm.design_cascade(BAND_HZ, FINEST_FSR_HZ, noise_w=5e-5, wrong_order_rate=1e-12)
    message = str(raised.value)
    assert raised.value.parameter == "wrong_order_rate"
    assert f"at most {MAX_STAGES} stages" in message and "the best is" in message
    best = float(message.split("the best is ")[1].split()[0])
    assert best > 1e-12
    for remedy in ("power_w", "noise_w", "finest_fsr_hz"):
        assert remedy in message

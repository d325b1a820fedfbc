"""The order-error physics of a cascade (:mod:`wavemeter.model.orders`): each posterior's
mean over readings is the rate it predicts, checked by Monte Carlo."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy import special

from wavemeter.model import (
    any_error_probability,
    edge_error_probability,
    handover_error_probability,
    handover_error_rate,
    wrap_error_probability,
)

SAMPLES = 400_000


@pytest.mark.parametrize("std_over_fsr", [0.15, 0.25, 0.4])
def test_handover_posterior_averages_to_the_rate_seen(std_over_fsr):
    rng = np.random.default_rng(1)
    fsr = 1.0
    error = rng.normal(0.0, std_over_fsr, SAMPLES)
    residual = (error + fsr / 2) % fsr - fsr / 2  # the order nearest is taken
    wrong = np.abs(error) > fsr / 2
    posterior = handover_error_probability(residual, fsr, std_over_fsr)
    seen, rate = wrong.mean(), float(handover_error_rate(fsr, std_over_fsr))
    tolerance = 4 * math.sqrt(rate * (1 - rate) / SAMPLES)
    assert abs(seen - rate) < tolerance
    assert abs(posterior.mean() - rate) < tolerance
    # and readings that were wrong carry more of it than readings that were right
    assert posterior[wrong].mean() > posterior[~wrong].mean()


def test_handover_posterior_limits():
    fsr, std = 1.0, 0.05
    assert handover_error_probability(0.0, fsr, std) < 1e-40
    # a residual half an FSR out is as likely from either neighbouring order
    assert handover_error_probability(0.5, fsr, std) == pytest.approx(0.5, rel=1e-9)
    np.testing.assert_allclose(
        handover_error_probability(np.array([-0.3, 0.3]), fsr, std),
        handover_error_probability(np.array([0.3, -0.3]), fsr, std),
        rtol=1e-15,
    )
    assert handover_error_probability(0.2, fsr, 0.0) == 0.0
    # far more noise than FSR: every order alike, among the 2 * 3 + 1 weighed
    assert handover_error_probability(0.0, fsr, 1e3) == pytest.approx(6 / 7, rel=1e-5)


def test_edge_probability_is_the_normal_tail():
    assert edge_error_probability(0.0, 1.0) == pytest.approx(0.5)
    assert edge_error_probability(3.0, 1.5) == pytest.approx(0.5 * special.erfc(2 / math.sqrt(2)))


def test_wrap_posterior_averages_to_the_wraps_seen():
    """Truth uniform over a band narrower than the period, estimates wrapped into the
    period about the band's middle: the posterior's mean is the share that wrapped."""
    rng = np.random.default_rng(2)
    period, low, high, std = 1.0, -0.4, 0.4, 0.06
    truth = rng.uniform(low, high, SAMPLES)
    estimate = truth + rng.normal(0.0, std, SAMPLES)
    wrapped = np.abs(estimate) > period / 2
    estimate = (estimate + period / 2) % period - period / 2
    posterior = wrap_error_probability(estimate, std, (low, high), period)
    seen = wrapped.mean()
    tolerance = 4 * math.sqrt(seen / SAMPLES)
    assert seen > 1e-3  # the check has something to count
    assert abs(posterior.mean() - seen) < tolerance
    # an estimate far outside the band on either side has no weight anywhere: unknown
    assert wrap_error_probability(np.array([0.49]), 1e-4, (low, high), period)[0] == 1.0


def test_any_error_probability_keeps_tiny_probabilities():
    tiny = np.array([[1e-18], [2e-18], [3e-18]])
    assert any_error_probability(tiny)[0] == pytest.approx(6e-18, rel=1e-12)
    assert any_error_probability(np.array([[0.5], [0.5]]))[0] == pytest.approx(0.75)
    assert not np.signbit(any_error_probability(np.zeros((3, 2)))).any()


def test_any_error_probability_of_a_certain_error_is_one_without_a_warning():
    """A stage whose order is surely wrong (a reading far outside the band)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert any_error_probability(np.array([[1.0, 0.0], [0.5, 0.0]])).tolist() == [1.0, 0.0]

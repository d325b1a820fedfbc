"""The wrong-order rates of a cascade's design search (``wavemeter.model.cascade_search``) as
logarithms: the coarsest stage's closed-form wrap rate against a numerical integral of
``edge_error_probability``, the series of its tail integral against the direct form, and
the hand-over rate against ``handover_error_rate``, also where the rates underflow.

These test the module's private functions, hence the file named after the module.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from wavemeter.model.cascade_search import (
    _SERIES_MARGIN,
    _log_edge_rate,
    _log_handover_rate,
    _log_tail_integral,
)
from wavemeter.model.orders import edge_error_probability, handover_error_rate

from .helpers import band_average_edge_rate


@pytest.mark.parametrize(
    ("coarsest_fsr_hz", "std_hz", "width_hz"),
    [
        (4.6e12, 0.08e12, 4.4e12),  # margin 1.25: the usual case
        (4.6e12, 0.03e12, 4.4e12),  # margin 3.3
        (6.0e12, 2.0e12, 4.4e12),  # s_0 comparable with the band: both limits matter
        (5.0e12, 0.5e9, 4.4e12),  # margin 600: far in the tail
        (1e12, 1e11, 1e3),  # a band narrow against s_0
    ],
)
def test_closed_form_wrap_rate_is_the_band_average_of_q(coarsest_fsr_hz, std_hz, width_hz):
    closed = math.exp(_log_edge_rate(coarsest_fsr_hz, std_hz, width_hz))
    numeric = band_average_edge_rate(coarsest_fsr_hz, std_hz, width_hz)
    if numeric > 1e-300:
        assert closed == pytest.approx(numeric, rel=1e-6)
    else:  # beyond doubles: the log form still orders designs
        assert _log_edge_rate(coarsest_fsr_hz, std_hz, width_hz) < math.log(1e-300)


def test_tail_integral_series_continues_the_direct_form():
    # g(z) = phi(z) - z Q(z); the series takes over at _SERIES_MARGIN. log g falls with
    # slope about -z (2e-10 apart: 2e-8 lower); a wrong series term shows (15 z^-4 = 1.5e-7)
    below = _log_tail_integral(_SERIES_MARGIN * (1 - 1e-12))
    above = _log_tail_integral(_SERIES_MARGIN * (1 + 1e-12))
    assert above == pytest.approx(below - _SERIES_MARGIN**2 * 2e-12, abs=1e-10)
    direct = math.log(
        math.exp(-0.5 * 30.0**2) / math.sqrt(2 * math.pi) - 30.0 * edge_error_probability(30, 1)
    )
    assert _log_tail_integral(30.0) == pytest.approx(direct, abs=1e-6)


def test_log_handover_rate_is_the_log_of_orders_rate():
    margins = np.array([0.1, 1.0, 3.0, 8.0, 20.0])
    fsr_hz = 50e9
    rates = handover_error_rate(fsr_hz, fsr_hz / (2.0 * margins))
    np.testing.assert_allclose(np.exp(_log_handover_rate(margins)), rates, rtol=1e-12)
    deep = _log_handover_rate(np.array([100.0, 1000.0]))  # the rates underflow
    assert np.all(np.isfinite(deep)) and deep[1] < deep[0] < math.log(1e-300)

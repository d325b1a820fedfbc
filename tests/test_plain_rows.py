"""A live readout's one-row conversion accepts exactly the rows convert_rows finds valid,
and gives them the same numbers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wavemeter.io import ColumnRequest
from wavemeter.io.checks import ColumnChecks
from wavemeter.io.convert import PlainRowConverter, convert_rows
from wavemeter.io.plan import plan_columns
from wavemeter.io.source import Source

HEADER = ("P1_dBm", "P2_mW", "P3_uW", "P4", "Temp (C)")
#: the rules' edges: power-meter codes, the dBm limits, zero and negative powers, overflow,
#: no number
EDGES = [-210.0, -200.0, -199.9, 60.0, 60.0001, 75.0, 0.0, -0.0, -1.0, 9.91e37, 1e20, 1e308]
EDGES += [np.nan, np.inf, -np.inf]
#: a plausible value in every unit of the header (often enough that whole rows are valid)
PLAUSIBLE = st.floats(min_value=-40.0, max_value=40.0)
VALUES = st.one_of(PLAUSIBLE, st.sampled_from(EDGES), st.floats(allow_infinity=True))


def plan_of(header, temperature: bool, request: ColumnRequest | None = None):
    """The plan of a live readout's header line (as ``wavemeter stream`` makes it)."""
    source = Source({column: (-1,) for column in header}, load=None)
    request = request or ColumnRequest()
    return plan_columns(source, request, need_x=False, extras=(False, temperature))


@pytest.mark.slow
@settings(max_examples=600, deadline=None)
@given(row=st.fixed_dictionaries({name: VALUES for name in HEADER}))
def test_plain_rows_are_the_valid_rows_of_convert_rows(row):
    plan = plan_of(HEADER, temperature=True)
    converted = PlainRowConverter.of(plan).convert(row)
    data = {name: np.array([value]) for name, value in row.items()}
    table = convert_rows(plan, data, 0, str, ColumnChecks())
    assert (converted is None) == bool(table.invalid[0])
    if converted is not None:
        powers_w, temperature_k = converted
        np.testing.assert_array_equal(powers_w, table.powers_w[0])
        assert temperature_k == table.temperature_k[0]


def test_plans_with_a_coarse_column_are_left_to_convert_rows():
    """A coarse column without a unit takes the unit its first values choose, which one
    row cannot tell."""
    header = ("P1", "P2", "P3", "coarse")
    assert PlainRowConverter.of(plan_of(header, temperature=False)) is not None
    request = ColumnRequest(coarse="coarse")
    assert PlainRowConverter.of(plan_of(header, False, request)) is None

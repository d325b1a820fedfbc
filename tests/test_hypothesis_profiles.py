"""`make test` gives the same result on every run: its property tests draw the same examples
every run, keep no database of failures between runs and time nothing (the profile
conftest.py loads); `make fuzz` draws new ones from a printed seed (the "fuzz" profile)."""

from __future__ import annotations

import importlib
import pkgutil

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import tests

from .helpers import DEFAULT_PROFILE, FUZZ_PROFILE


@pytest.fixture
def default_run(request):
    if request.config.getoption("hypothesis_profile", default=None) == FUZZ_PROFILE:
        pytest.skip("run with the fuzz profile, which draws new examples on purpose")


def property_tests() -> dict:
    """Every hypothesis test of the suite, by module and name."""
    found = {}
    for module_info in pkgutil.iter_modules(tests.__path__):
        if module_info.name.startswith("test_"):
            module = importlib.import_module(f"tests.{module_info.name}")
            for name, value in vars(module).items():
                if getattr(value, "is_hypothesis_test", False):
                    found[f"{module_info.name}.{name}"] = value
    return found


def test_the_profiles_are_registered_as_make_test_and_make_fuzz_need():
    default, fuzz = settings.get_profile(DEFAULT_PROFILE), settings.get_profile(FUZZ_PROFILE)
    assert default.derandomize and default.database is None and default.deadline is None
    assert not fuzz.derandomize and fuzz.database is None


def test_every_property_test_of_the_default_run_is_derandomised(default_run):
    found = property_tests()
    assert {"test_fuzz_calibration_files.test_a_mutated_file_loads_usable_or_is_refused"} < set(
        found
    )
    for name, test in found.items():
        # hypothesis keeps the settings a test runs with here (there is no public getter)
        chosen = test._hypothesis_internal_use_settings
        assert chosen.derandomize, name
        assert chosen.database is None, name


def test_a_property_test_draws_the_same_examples_on_every_run(default_run):
    drawn: list[list] = []

    @given(st.floats(allow_nan=False), st.text(max_size=5))
    def probe(number, text):
        drawn[-1].append((number, text))

    for _ in range(2):
        drawn.append([])
        probe()
    assert len(drawn[0]) >= 50 and drawn[0] == drawn[1]

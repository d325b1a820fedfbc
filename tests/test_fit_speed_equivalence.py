"""The lean fit diagnostics compute the numbers of the code they replaced (issue 13).

``misfit_report`` (with :mod:`wavemeter.stats`, then in ``residual_tests``) and ``cone_vectors``
were rewritten to be fast on large sweeps without changing a decision or a reported number
beyond rounding. Each case here is computed twice: with today's code and with the code of
``FROZEN_COMMIT`` (read from git and loaded beside the package, its own ``cone_vectors``
and ``residual_tests`` included), on Table 1 devices, clean and with the faults the report
names, through each way the cosine tests are computed (cosine coefficients from DCTs or,
forced at any length, from today's block Taylor series; the fit's directions formed or
applied through their structure; cosines formed for short sweeps), and through
``Calibrator.fit``.

Tolerances: the two computations group the same sums differently, so a well-conditioned
number agrees to a few rounding units times its condition (~10 here): ``RTOL = 1e-12``. A
number computed along a direction the fit nearly absorbs (a fringe nearly inside the first
cosines on a partial sweep; the directions ``ProjectedCosineColumns`` takes from a Gram
matrix, documented to ``1e-10`` of the columns' norms) is known to no better than its
condition times the rounding unit, by either code: there the bound is ``SPREAD_FACTOR``
times how far the reference itself moves when its inputs and its cosine transforms change
by one rounding unit (``reference_and_spread``). p-values are compared as ``log p``
(relative to ``|log p| + 1``). Warnings must be the same strings: their numbers are printed
to 2-3 digits; where issue 29 changed the naming by design (``RENAMED``), the causes named
today are checked instead, and the tests added since (``ADDED_P_VALUES``) are not compared.
"""

from __future__ import annotations

import dataclasses
import inspect
import subprocess
import sys
import types
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy import fft, linalg

import wavemeter as wm
from wavemeter.calibration.checks import misfit, misfit_causes
from wavemeter.calibration.fitting import steps
from wavemeter.calibration.methods import learned
from wavemeter.calibration.models.learned_fit import fit_learned_map
from wavemeter.model import cone
from wavemeter.simulation.drift import flicker_power_noise, slow_power_drift
from wavemeter.stats import blocks, cosine_transform, nested_tests, projection

from .helpers import darken, narrow_band_case, wideband_report, wideband_sweep

#: the commit whose misfit.py, residual_tests.py and cone.py are the reference
FROZEN_COMMIT = "3fe49e563989582a87f5ee23cd420213ee3abe75"
FROZEN_FILES = {
    "model._frozen_cone": "src/wavemeter/model/cone.py",
    "calibration._frozen_residual_tests": "src/wavemeter/calibration/residual_tests.py",
    "calibration._frozen_misfit": "src/wavemeter/calibration/misfit.py",
}
ROOT = Path(__file__).resolve().parents[1]
POWER_W = 1e-3
NOISE_W = 5e-7  # Table 1
FSR_HZ = 50e9
#: relative agreement of well-conditioned numbers (a few rounding units times ~10)
RTOL = 1e-12
#: a difference within this many times the reference's own change under a rounding-level
#: change of its cosine transforms is rounding
SPREAD_FACTOR = 30.0
PERTURBED_RUNS = 2
#: p-values of tests the report has made since the frozen code, and causes it names (issue
#: 29): a wide sweep's polynomial in frequency, a rounded axis
ADDED_P_VALUES = ("band", "band_slope", "band_remainder", "quantised_axis")
ADDED_CAUSES = ("quantised_axis",)
#: cases whose warnings issue 29 changed by design, with the causes named today: over
#: several FSRs a structure a polynomial in frequency explains is named by what it is (a
#: phase even in frequency, ports that change each in its own way, or a power drift that a
#: responsivity slope would mimic); their numbers are still the frozen code's
RENAMED = {
    "dispersion": ("dispersion",),
    "power_drift": ("power_drift",),
    "thermal_phase": ("dispersion",),
}
RENAMED_WIDEBAND = {1: ("dispersion",)}


# ---------------------------------------------------------------------- the frozen code
def _frozen_source(path: str) -> str:
    try:
        done = subprocess.run(
            ["git", "-C", str(ROOT), "show", f"{FROZEN_COMMIT}:{path}"],
            capture_output=True,
            text=True,
            check=False,
        )
    except OSError:
        done = None
    if done is None or done.returncode != 0:
        pytest.skip(f"the reference code needs git and commit {FROZEN_COMMIT[:7]}")
    return (
        done.stdout.replace("from ..model.cone import", "from ..model._frozen_cone import")
        .replace("from .residual_tests import", "from ._frozen_residual_tests import")
        .replace("from .misfit import", "from ._frozen_misfit import")
    )


@pytest.fixture(scope="module")
def frozen():
    """The frozen modules, by short name (``cone``, ``residual_tests``, ``misfit``)."""
    loaded = {}
    with pytest.MonkeyPatch.context() as patch:
        for name, path in FROZEN_FILES.items():
            full = f"wavemeter.{name}"
            module = types.ModuleType(full)
            module.__package__ = full.rpartition(".")[0]
            module.__file__ = f"{FROZEN_COMMIT[:7]}:{path}"
            patch.setitem(sys.modules, full, module)
            exec(compile(_frozen_source(path), module.__file__, "exec"), module.__dict__)
            loaded[name.rpartition("._frozen_")[2]] = module
        yield types.SimpleNamespace(**loaded)


def _perturbed(value, rng):
    """A float array moved by a rounding unit (relative, random); anything else as is."""
    if not isinstance(value, np.ndarray) or value.dtype != float or value.ndim == 0:
        return value
    return value * (1.0 + np.finfo(float).eps * rng.standard_normal(value.shape))


def _frozen_report(frozen, rng=None):
    """The frozen ``misfit_report``, taking (and ignoring) arguments added since; with a
    generator ``rng``, its array arguments moved by a rounding unit."""
    known = inspect.signature(frozen.misfit.misfit_report).parameters

    def report(*args, **options):
        if rng is not None:
            args = [_perturbed(value, rng) for value in args]
            options = {name: _perturbed(value, rng) for name, value in options.items()}
        return frozen.misfit.misfit_report(
            *args, **{name: value for name, value in options.items() if name in known}
        )

    return report


@pytest.fixture(params=["default", "projected", "formed", "taylor", "taylor-projected", "blocks"])
def path(request, frozen, monkeypatch):
    """Force a way of computing the cosine tests: ``projected`` applies the fit's directions
    through their structure (both codes), ``formed`` forms the cosine columns (both codes),
    ``taylor`` takes today's cosine coefficients from block Taylor series at any length (the
    reference from DCTs); ``blocks`` runs today's passes over the readings in blocks of 97
    rows (the sweeps here are shorter than one block of ``ROW_BLOCK``)."""
    if request.param == "blocks":
        monkeypatch.setattr(blocks, "ROW_BLOCK", 97)
    for module in (nested_tests, frozen.residual_tests):
        if request.param.endswith("projected"):
            monkeypatch.setattr(module, "MAX_FORMED_DIRECTIONS", 0)
        if request.param == "formed":
            monkeypatch.setattr(module, "MIN_DCT_READINGS", 10**9)
    if request.param.startswith("taylor"):
        monkeypatch.setattr(cosine_transform, "MIN_TAYLOR_BLOCK", 1)
    return request.param


# ---------------------------------------------------------------------- comparisons
def _numbers(report) -> dict:
    """The numbers of a report (a ``MisfitReport``, its ``to_dict`` or a fit's attributes)
    by name, p-values as ``log p``; None where there is none."""
    fields = report if isinstance(report, dict) else report.to_dict()
    numbers = {}
    for name, value in fields.items():
        if name == "p_values":
            for test, p_value in value.items():
                with np.errstate(divide="ignore"):
                    numbers[f"log p[{test}]"] = None if p_value is None else np.log(p_value)
        elif name not in ("warnings", "noise_method", "misfit", "raised", "recorded"):
            numbers[name] = None if value is None else np.asarray(value, dtype=float)
    return numbers


def _perturbed_transform(transform, rng):
    """``transform`` with an error of one rounding unit of its outputs' RMS added: another
    computation of the same cosine coefficients, as exact."""

    def perturbed(values, size):
        result = transform(values, size)
        scale = np.sqrt(np.mean(np.square(result), axis=0, keepdims=True))
        return result + np.finfo(float).eps * scale * rng.standard_normal(result.shape)

    return perturbed


def reference_and_spread(compute, frozen) -> tuple[dict, dict]:
    """The frozen code's numbers, ``compute(report)`` with ``report`` its
    ``misfit_report``, and how far they move when its inputs and its cosine transforms
    change by a rounding unit (``PERTURBED_RUNS`` times): the conditioning of each number,
    which bounds what another computation of it can agree to."""
    reference = compute(_frozen_report(frozen))
    spread = {name: 0.0 for name in _numbers(reference)}
    rng = np.random.default_rng(0)
    module = frozen.residual_tests
    with pytest.MonkeyPatch.context() as patch:
        for name in ("_cosine_analysis", "_cosine_synthesis"):
            patch.setattr(module, name, _perturbed_transform(getattr(module, name), rng))
        for _ in range(PERTURBED_RUNS):
            moved = _numbers(compute(_frozen_report(frozen, rng)))
            for name, value in _numbers(reference).items():
                if value is not None and moved[name] is not None:
                    with np.errstate(invalid="ignore"):
                        gap = np.nan_to_num(np.abs(moved[name] - value), nan=0.0)
                    spread[name] = np.maximum(spread[name], gap)
    return reference, spread


def assert_same_numbers(report, reference, spread) -> None:
    """Warnings equal as strings; every number within ``RTOL`` of the reference's or
    ``SPREAD_FACTOR`` times its spread under a rounding change (``log p`` relative to
    ``|log p| + 1``)."""
    new, old = _numbers(report), _numbers(reference)
    # the tests added since the frozen code (issue 29: a wide sweep's polynomial in
    # frequency, a rounded axis) are the only numbers it does not have
    assert new.keys() - old.keys() <= {f"log p[{name}]" for name in ADDED_P_VALUES}
    assert old.keys() <= new.keys()
    for name, expected in old.items():
        value = new[name]
        if expected is None or value is None:
            assert value is expected, name
            continue
        assert value.shape == expected.shape, name
        finite = np.isfinite(expected)
        np.testing.assert_array_equal(np.isfinite(value), finite, err_msg=name)
        size = np.abs(expected) + 1.0 if name.startswith("log p") else np.abs(expected)
        with np.errstate(over="ignore"):  # a number that is rounding noise allows anything
            allowed = np.maximum(RTOL * size, SPREAD_FACTOR * spread[name])
        gap = np.abs(value[finite] - expected[finite])
        assert np.all(gap <= np.broadcast_to(allowed, expected.shape)[finite]), (
            name,
            value,
            expected,
            spread[name],
        )


def assert_same_report(report, reference, spread, renamed=None) -> None:
    """Today's report is the frozen one: the same warnings, or for a case whose naming
    issue 29 changed (``renamed``, the causes named today), those causes; the same numbers."""
    new = report if isinstance(report, dict) else report.to_dict()
    old = reference if isinstance(reference, dict) else reference.to_dict()
    if renamed is None:
        assert new["warnings"] == old["warnings"]
    else:
        assert tuple(note["cause"] for note in new["warnings"]) == renamed
    assert (new["noise_method"], new["misfit"]) == (old["noise_method"], old["misfit"])
    assert_same_numbers(new, old, spread)


# ---------------------------------------------------------------------- the cases
def _learned_call(frequency, powers, *, scale=None, affine=False, **options):
    """Arguments of ``misfit_report`` after a learned fit (centre = middle of the sweep)."""
    center = 0.5 * (frequency.min() + frequency.max())
    fit = fit_learned_map(
        powers, frequency, center, fsr_hz=FSR_HZ, fsr_tolerance=0.2, scale=scale, affine=affine
    )
    if affine:
        options.update(offset_w=fit.map_[:, 3], offset_std_w=np.full(powers.shape[1], 2e-8))
    return (powers, frequency, center, fit.delay_s, fit.map_[:, :3]), {"scale": scale, **options}


def _sweep(ports, seed, samples, span_fsr=1.0, power_w=POWER_W, noise_w=NOISE_W, **kw):
    device = kw.pop("device", None) or wm.Interferometer.table1(ports, seed=seed)
    frequency = device.sweep_hz(samples, span_fsr)
    return frequency, device.powers(frequency, power_w, noise_w, rng=seed + 1, **kw)


def case_clean():
    return _learned_call(*_sweep(3, 7, 3000, 4.0))


def case_power_drift():
    return _learned_call(*_sweep(3, 6, 1500, 3.0, POWER_W * slow_power_drift(1500, 0.5, rng=6)))


def case_flicker():
    return _learned_call(*_sweep(4, 8, 400, power_w=POWER_W * flicker_power_noise(400, 0.01, 8)))


def case_thermostat():
    device = dataclasses.replace(wm.Interferometer.table1(3, seed=10), thermal_phase_rad_per_k=1.0)
    cycle = 0.025 * np.sin(2 * np.pi * 3 * np.arange(2000) / 2000)
    temperature = device.reference_temperature_k + cycle
    return _learned_call(*_sweep(3, 10, 2000, 3.0, device=device, temperature_k=temperature))


def case_dispersion():
    device = dataclasses.replace(wm.Interferometer.table1(3, seed=14), dispersion_s2=1e-24)
    return _learned_call(*_sweep(3, 14, 2000, 10.0, device=device))


def case_offsets():
    dark = np.array([3e-6, -2e-6, 1e-6, 0.0])
    device = dataclasses.replace(wm.Interferometer.table1(4, seed=18), dark_offset_w=dark)
    power = POWER_W * slow_power_drift(1000, 0.3, rng=18)
    frequency, powers = _sweep(4, 18, 1000, 2.0, power, device=device)
    return _learned_call(frequency, powers, scale=power / power.mean(), affine=True)


def case_unequal_noise():
    noise = np.array([5e-7, 5e-7, 5e-6])
    return _learned_call(*_sweep(3, 24, 800, 1.0, noise_w=noise))


def case_weak_port():
    device = wm.Interferometer.table1(3, seed=26)
    frequency, powers = _sweep(3, 26, 800, 2.0, device=device)
    powers[:, 2] = 0.02 * powers[:, 2] + NOISE_W * np.random.default_rng(27).normal(size=800)
    return _learned_call(frequency, powers)


def case_partial_span():
    return _learned_call(*_sweep(3, 28, 600, 0.5))


def case_nonlinear():
    frequency, powers = _sweep(3, 16, 600, 2.0)
    return _learned_call(frequency, powers - 0.01 * powers**2 / powers.max())


def case_noiseless():
    return _learned_call(*_sweep(3, 30, 500, 2.0, noise_w=0.0))


def case_short():
    return _learned_call(*_sweep(5, 32, 60, 3.0))


def case_fewest():
    return _learned_call(*_sweep(3, 34, 8, 1.0))


def case_two_way():
    frequency, _ = _sweep(3, 12, 1200, 2.0)
    two_way = np.concatenate([frequency[::2], frequency[::-2]])
    device = wm.Interferometer.table1(3, seed=12)
    ramp = np.linspace(0.0, 0.2, two_way.size)
    return _learned_call(two_way, device.powers(two_way, POWER_W, NOISE_W, 13, bias_drift_rad=ramp))


def case_thermal_phase():
    arguments, options, _, _ = narrow_band_case("phase")
    return arguments, options


def case_wideband():
    drift = slow_power_drift(4000, 0.0005, rng=71, cycles=5.0)
    sweep = wideband_sweep(4, 71, higher_phase_rad=(1.0, 0.1), power=drift)
    return sweep, sweep.phase_coefficients_rad


CASES = {
    name.removeprefix("case_"): value
    for name, value in sorted(globals().items())
    if name.startswith("case_") and name != "case_wideband"
}


def _report(function, case):
    arguments, options = case
    return function(*arguments, **options)


# ---------------------------------------------------------------------- the tests
def test_cone_vectors_are_todays_bit_for_bit(frozen):
    rng = np.random.default_rng(1)
    phase = rng.uniform(-30.0, 30.0, 1001)
    for power in (1.0, 2.5e-3, rng.uniform(0.5, 1.5, 1001)):
        new, old = cone.cone_vectors(phase, power), frozen.cone.cone_vectors(phase, power)
        assert new.shape == old.shape == (1001, 3) and new.dtype == old.dtype
        np.testing.assert_array_equal(new, old)
    # a scalar phase and a list give today's shapes too
    np.testing.assert_array_equal(cone.cone_vectors(0.3), frozen.cone.cone_vectors(0.3))
    np.testing.assert_array_equal(
        cone.cone_vectors([0.1, 0.2], [1.0, 2.0]), frozen.cone.cone_vectors([0.1, 0.2], [1.0, 2.0])
    )


@pytest.mark.slow
@pytest.mark.parametrize(
    ("samples", "orders"),
    [(7, 2), (130, 97), (4099, 193), (65536, 2), (65536, 385), (100003, 97), (100003, 385)],
)
def test_taylor_cosine_coefficients_are_the_dcts(samples, orders, monkeypatch):
    """The block Taylor series give scipy's DCT-II coefficients and DCT-III sums to
    rounding: ``1e-14`` of the values' RMS times ``sqrt(N)`` (the coefficients' scale),
    any length (a prime, blocks with a tail), any number of orders."""
    monkeypatch.setattr(cosine_transform, "MIN_TAYLOR_BLOCK", 1)
    rng = np.random.default_rng(samples + orders)
    values = rng.standard_normal((samples, 2))
    expected = fft.dct(values, type=2, axis=0)[:orders] / 2.0
    got = cosine_transform.cosine_analysis(values, orders)
    assert np.abs(got - expected).max() <= 1e-14 * np.sqrt(samples)
    coefficients = rng.standard_normal((orders - 1, 2))
    padded = np.zeros((samples, 2))
    padded[1:orders] = coefficients / 2.0
    expected = fft.dct(padded, type=3, axis=0)
    got = cosine_transform.cosine_synthesis(coefficients, samples)
    assert np.abs(got - expected).max() <= 1e-14 * np.sqrt(orders)


@pytest.mark.parametrize("rank", [3, 4])
def test_orthonormal_columns_span_what_orth_spans(rank, monkeypatch):
    """Householder QR and the SVD of its triangle give scipy's ``orth``: the same rank
    (here a fourth column that is, or is not, a combination of the others) and the same
    projector, to rounding."""
    monkeypatch.setattr(blocks, "ROW_BLOCK", 97)
    rng = np.random.default_rng(rank)
    columns = rng.standard_normal((1000, 4))
    if rank == 3:
        columns[:, 3] = columns[:, :3] @ np.array([0.5, -2.0, 1.0])
    basis = blocks.orthonormal_columns(columns)
    expected = linalg.orth(columns)
    assert basis.shape == expected.shape == (1000, rank)
    np.testing.assert_allclose(basis.T @ basis, np.eye(rank), atol=1e-14)
    np.testing.assert_allclose(basis @ (basis.T @ columns), columns, atol=1e-13)
    np.testing.assert_allclose(basis @ basis.T, expected @ expected.T, atol=1e-14)


def test_the_projector_keeps_what_gram_schmidt_kept():
    """The coupled directions are orthonormalised by Householder QR (Gram-Schmidt was
    4.3 s for the 192 directions of a corrected axis): in order, signs as Gram-Schmidt's,
    a direction the ones before absorb dropped (here the fourth, a combination of two);
    and a span of no coefficients is empty, not an error (a cosine test whose directions
    all lie inside the fit's)."""
    rng = np.random.default_rng(29)
    samples, ports = 500, 3
    basis = blocks.orthonormal_columns(rng.standard_normal((samples, 4)))
    coupled = rng.standard_normal((samples, ports, 6))
    coupled[:, :, 3] = coupled[:, :, 0] - 2.0 * coupled[:, :, 2]
    projector = projection.Projector(basis, coupled)
    kept = []  # Gram-Schmidt, twice, as the projector did before
    for index in (0, 1, 2, 3, 4, 5):
        column = projector.per_port(coupled[:, :, index]).copy()
        for _ in range(2):
            for previous in kept:
                column -= np.sum(previous * column) * previous
        if np.linalg.norm(column) > projection.RANK_TOLERANCE * np.linalg.norm(coupled[..., index]):
            kept.append(column / np.linalg.norm(column))
    assert projector.coupled.shape == (samples, ports, 5) and len(kept) == 5
    np.testing.assert_allclose(projector.coupled, np.stack(kept, axis=2), atol=1e-12)
    assert projector.span(np.zeros((projector.size, 0))).shape == (samples, ports, 0)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(CASES))
def test_misfit_report_is_todays(name, frozen, path):
    case = CASES[name]()
    reference, spread = reference_and_spread(lambda report: _report(report, case), frozen)
    assert_same_report(_report(misfit.misfit_report, case), reference, spread, RENAMED.get(name))


@pytest.mark.slow
def test_the_cases_cover_every_cause(frozen):
    """The cases are not vacuous: between them the reference names every cause it knows
    (the causes added since are tested in test_misfit_causes.py)."""
    causes = set()
    for case in CASES.values():
        causes.update(_report(_frozen_report(frozen), case()).causes)
    assert causes == set(misfit_causes.CAUSES) - set(ADDED_CAUSES)


@pytest.mark.slow
@pytest.mark.parametrize("taylor", [False, True])
@pytest.mark.parametrize("degree", [1, 2])
def test_wideband_report_is_todays(degree, taylor, frozen, monkeypatch):
    """Each reading's map, a design and two phase coefficients (a stack of maps)."""
    sweep, coefficients = case_wideband()
    if taylor:
        monkeypatch.setattr(cosine_transform, "MIN_TAYLOR_BLOCK", 1)
    new = wideband_report(sweep, coefficients, degree)

    def compute(report):
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr("tests.test_misfit_wideband.misfit_report", report)
            return wideband_report(sweep, coefficients, degree).to_dict()

    assert_same_report(new, *reference_and_spread(compute, frozen), RENAMED_WIDEBAND.get(degree))


def _fit(frequency, powers, monitor=None, **options) -> dict:
    """A learned fit's diagnostics, warnings and what it takes from the report."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cal = wm.Calibrator(FSR_HZ, **options).fit(powers, frequency, power_monitor_w=monitor)
    return {
        **cal.diagnostics_["fit"],
        "raised": [str(note.message) for note in caught],
        "recorded": cal.diagnostics_["warnings"],
        **{
            name: getattr(cal, name)
            for name in ("port_noise_std_w_", "noise_dof_", "parameter_covariance_", "map_")
        },
    }


def _monitored_offsets():
    dark = np.array([3e-6, -2e-6, 1e-6])
    device = dataclasses.replace(wm.Interferometer.table1(3, seed=18), dark_offset_w=dark)
    power = POWER_W * slow_power_drift(1000, 0.3, rng=18)
    return (*_sweep(3, 18, 1000, 2.0, power, device=device), power)


FIT_CASES = {
    "clean": lambda: (*_sweep(3, 7, 3000, 4.0), None),
    "power_drift": lambda: (
        *_sweep(3, 6, 1500, 3.0, POWER_W * slow_power_drift(1500, 0.5, rng=6)),
        None,
    ),
    "dead_port": lambda: (lambda f, p: (f, darken(p, [2]), None))(*_sweep(4, 1, 2001)),
    "monitored_offsets": _monitored_offsets,
}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(FIT_CASES))
@pytest.mark.parametrize("retrieval", ["pinv", "ml"])
def test_calibrator_fit_is_todays(name, retrieval, frozen, monkeypatch):
    """Through ``Calibrator.fit`` (cosine coefficients from Taylor series, passes in blocks
    of 997 readings): the diagnostics, the warnings and what the fit takes from the report
    (the noise after a misfit, the parameter covariance)."""
    frequency, powers, monitor = FIT_CASES[name]()
    monkeypatch.setattr(cosine_transform, "MIN_TAYLOR_BLOCK", 1)
    monkeypatch.setattr(blocks, "ROW_BLOCK", 997)
    new = _fit(frequency, powers, monitor, retrieval=retrieval)

    def compute(report):
        with pytest.MonkeyPatch.context() as patch:
            for module in (steps, learned):
                patch.setattr(module, "misfit_report", report)
            return _fit(frequency, powers, monitor, retrieval=retrieval)

    reference, spread = reference_and_spread(compute, frozen)
    renamed = RENAMED.get(name)
    if renamed is None:
        assert (new["raised"], new["recorded"]) == (reference["raised"], reference["recorded"])
    else:
        assert tuple(note["cause"] for note in new["recorded"]) == renamed
        assert len(new["raised"]) == len(renamed)
    assert_same_report(new, reference, spread, renamed)

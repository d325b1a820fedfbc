"""One map per reading (a map that changes with frequency): the model functions on a stack.

Reading ``k`` of a stack is handled with ``map_[k]`` exactly as one reading with that map
alone: a stack of one map repeated gives the single-map result, a stack of different maps
gives what a loop over the readings gives, both to 1e-12 (the rounding of the two paths,
which factor the same matrices in different orders, is ~1e-15). Noiseless readings give
back their phase to 1e-10 rad.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg

import wavemeter as wm
from wavemeter.exceptions import InputError
from wavemeter.model.cone import cone_vectors, wrap_phase_rad
from wavemeter.model.limits import crlb_frequency_std
from wavemeter.model.retrieval import (
    cone_ml_phase_rad,
    pinv_phase_rad,
    source_power_ratio,
    stacked_pinv,
)
from wavemeter.model.uncertainty import ml_phase_gradient, pinv_phase_gradient

#: agreement of the stacked and the single-map paths (relative, and rad for phases)
AGREEMENT = 1e-12
#: phases of noiseless readings (rad)
NOISELESS = 1e-10
#: relative change of every map entry from reading to reading (a slowly varying map)
PERTURBATION = 0.02
FSR_HZ = 50e9


def _stack(ports: int, samples: int, seed: int):
    """A Table-1 map (n, 3), a stack of perturbed copies (N, n, 3), phases (N,) and source
    powers (N,, relative) of readings, and noiseless readings ``P_k A_k u(t_k)`` (N, n)."""
    rng = np.random.default_rng(seed)
    single = wm.Interferometer.table1(ports, seed=seed).true_map()
    stack = single * (1.0 + PERTURBATION * rng.standard_normal((samples, ports, 3)))
    phase = rng.uniform(-np.pi, np.pi, samples)
    power = rng.uniform(0.5, 2.0, samples)
    readings = np.einsum("kji,ki->kj", stack, cone_vectors(phase, power))
    return single, stack, phase, power, readings


def _noisy(readings, seed: int):
    """Readings off the cone (1 % of their scale): the secular root is not at zero."""
    rng = np.random.default_rng(seed + 100)
    return readings + 0.01 * np.abs(readings).mean() * rng.standard_normal(readings.shape)


def _port_noise(ports: int) -> np.ndarray:
    """Unequal detector noise per port (W): the weighted paths."""
    return 1e-3 * np.resize([1.0, 3.0, 0.5], ports)


def _assert_same(actual, expected):
    """Equal to AGREEMENT relative to each entry or to the largest entry of ``expected``."""
    expected = np.asarray(expected)
    np.testing.assert_allclose(
        actual, expected, rtol=AGREEMENT, atol=AGREEMENT * np.abs(expected).max()
    )


def _assert_same_phase(actual, expected, tolerance=AGREEMENT):
    np.testing.assert_allclose(wrap_phase_rad(actual - expected), 0.0, atol=tolerance)


PORTS = [3, 4, 5]


@pytest.mark.parametrize("ports", PORTS)
def test_a_stack_of_one_map_gives_the_single_map_result(ports):
    single, _, phase, power, readings = _stack(ports, 300, seed=ports)
    readings = _noisy(readings, ports)
    samples = readings.shape[0]
    same = np.broadcast_to(single, (samples, ports, 3))
    for noise in (None, _port_noise(ports)):
        retrieved = cone_ml_phase_rad(readings, single, noise_std_w=noise)
        _assert_same_phase(cone_ml_phase_rad(readings, same, noise_std_w=noise), retrieved)
        _assert_same(
            source_power_ratio(readings, same, retrieved, noise),
            source_power_ratio(readings, single, retrieved, noise),
        )
    noise = _port_noise(ports)
    _assert_same(
        ml_phase_gradient(same, phase, power, noise),
        ml_phase_gradient(single, phase, power, noise),
    )
    for noise_std in (1e-3, noise):
        expected = crlb_frequency_std(single, phase, power, noise_std, FSR_HZ)
        _assert_same(crlb_frequency_std(same, phase, power, noise_std, FSR_HZ), expected)
        fsr = np.full(samples, FSR_HZ)
        _assert_same(crlb_frequency_std(same, phase, power, noise_std, fsr), expected)
    inverse = linalg.pinv(single)
    inverses = stacked_pinv(same)
    _assert_same(inverses, np.broadcast_to(inverse, inverses.shape))
    _assert_same_phase(pinv_phase_rad(readings, inverses), pinv_phase_rad(readings, inverse))
    _assert_same_phase(
        pinv_phase_rad(readings, inverse), wm.retrieve_phase_rad(readings, inverse), 0.0
    )
    _assert_same(pinv_phase_gradient(readings, inverses), pinv_phase_gradient(readings, inverse))


@pytest.mark.slow
@pytest.mark.parametrize("ports", PORTS)
def test_a_stack_of_maps_equals_a_loop_over_the_readings(ports):
    _, stack, phase, power, readings = _stack(ports, 200, seed=10 + ports)
    readings = _noisy(readings, ports)
    noise = _port_noise(ports)
    fsr = FSR_HZ * (1.0 + 1e-3 * np.linspace(-1.0, 1.0, phase.size))
    inverses = stacked_pinv(stack)
    for k in range(phase.size):
        _assert_same(inverses[k], linalg.pinv(stack[k]))
    one = [(readings[k : k + 1], stack[k]) for k in range(phase.size)]
    for weights in (None, noise):
        retrieved = cone_ml_phase_rad(readings, stack, noise_std_w=weights)
        looped = [cone_ml_phase_rad(p, a, noise_std_w=weights)[0] for p, a in one]
        _assert_same_phase(retrieved, looped)
        _assert_same(
            source_power_ratio(readings, stack, retrieved, weights),
            [
                source_power_ratio(p, a, retrieved[k : k + 1], weights)[0]
                for k, (p, a) in enumerate(one)
            ],
        )
    _assert_same_phase(
        pinv_phase_rad(readings, inverses),
        [pinv_phase_rad(p, inverses[k])[0] for k, (p, _) in enumerate(one)],
    )
    _assert_same(
        pinv_phase_gradient(readings, inverses),
        [pinv_phase_gradient(p, inverses[k])[0] for k, (p, _) in enumerate(one)],
    )
    _assert_same(
        ml_phase_gradient(stack, phase, power, noise),
        [ml_phase_gradient(a, phase[k], power[k], noise)[0] for k, (_, a) in enumerate(one)],
    )
    for noise_std in (1e-3, noise):
        _assert_same(
            crlb_frequency_std(stack, phase, power, noise_std, fsr),
            [
                crlb_frequency_std(a, phase[k], power[k], noise_std, fsr[k])
                for k, (_, a) in enumerate(one)
            ],
        )


@pytest.mark.parametrize("ports", PORTS)
def test_noiseless_readings_give_back_their_phase(ports):
    _, stack, phase, power, readings = _stack(ports, 2000, seed=20 + ports)
    for weights in (None, _port_noise(ports)):
        retrieved = cone_ml_phase_rad(readings, stack, noise_std_w=weights)
        _assert_same_phase(retrieved, phase, NOISELESS)
        np.testing.assert_allclose(
            source_power_ratio(readings, stack, phase, weights), power, rtol=NOISELESS
        )
    _assert_same_phase(pinv_phase_rad(readings, stacked_pinv(stack)), phase, NOISELESS)


def test_a_stack_is_not_read_as_one_map():
    """Each reading is retrieved with its own map: the shared map would miss by far more."""
    single, stack, phase, _, readings = _stack(4, 2000, seed=30)
    own = wrap_phase_rad(cone_ml_phase_rad(readings, stack) - phase)
    shared = wrap_phase_rad(cone_ml_phase_rad(readings, single) - phase)
    assert np.abs(own).max() < NOISELESS < np.abs(shared).max()


def _bad_calls():
    """(call, parameter it must name) for every kind of wrong shape or content."""
    _, stack, phase, power, readings = _stack(4, 12, seed=40)
    inverses = stacked_pinv(stack)
    noise = _port_noise(4)
    flat = stack.copy()
    flat[3, :, 2] = 0.0  # rank 2
    holed = stack.copy()
    holed[5, 1, 1] = np.nan
    fsr = np.full(phase.size, FSR_HZ)
    return [
        (lambda: cone_ml_phase_rad(readings, stack[:-1]), "map_"),
        (lambda: cone_ml_phase_rad(readings, stack[..., :2]), "map_"),
        (lambda: cone_ml_phase_rad(readings, stack[None]), "map_"),
        (lambda: cone_ml_phase_rad(readings[:, :-1], stack), "powers"),
        (lambda: cone_ml_phase_rad(readings, flat), "map_"),
        (lambda: cone_ml_phase_rad(readings, holed), "map_"),
        (lambda: cone_ml_phase_rad(readings, stack, noise_std_w=noise[:-1]), "noise_std_w"),
        (lambda: source_power_ratio(readings, stack[1:], phase), "map_"),
        (lambda: source_power_ratio(readings, stack, phase[:-1]), "phase_rad"),
        (lambda: pinv_phase_rad(readings, inverses[:-1]), "map_pinv"),
        (lambda: pinv_phase_rad(readings, inverses.transpose(0, 2, 1)), "map_pinv"),
        (lambda: pinv_phase_rad(readings[:, :-1], inverses), "powers"),
        (lambda: pinv_phase_gradient(readings, inverses[:-1]), "map_pinv"),
        (lambda: pinv_phase_gradient(readings, inverses[None]), "map_pinv"),
        (lambda: pinv_phase_gradient(readings[:, :-1], inverses), "powers"),
        (lambda: ml_phase_gradient(stack[:-1], phase, power, noise), "map_"),
        (lambda: ml_phase_gradient(stack, phase[:, None], power, noise), "phase_rad"),
        (lambda: ml_phase_gradient(stack, phase, power[:-1], noise), "power"),
        (lambda: ml_phase_gradient(stack, phase, power, noise[:-1]), "noise_std_w"),
        (lambda: crlb_frequency_std(stack[:-1], phase, power, noise, fsr), "map_"),
        (lambda: crlb_frequency_std(stack[..., :2], phase, power, noise, fsr), "map_"),
        (lambda: crlb_frequency_std(stack, phase[0], power, noise, fsr), "phase_rad"),
        (lambda: crlb_frequency_std(stack, phase, power[:-1], noise, fsr), "power"),
        (lambda: crlb_frequency_std(stack, phase, power, noise, fsr[:-1]), "fsr_hz"),
        (lambda: crlb_frequency_std(stack, phase, power, noise, -fsr), "fsr_hz"),
        (lambda: crlb_frequency_std(stack, phase, power, noise, 0.0), "fsr_hz"),
        (lambda: stacked_pinv(stack[0]), "map_"),
        (lambda: stacked_pinv(stack[:, :2]), "map_"),
        (lambda: stacked_pinv(flat), "map_"),
        (lambda: stacked_pinv(holed), "map_"),
    ]


@pytest.mark.parametrize(("index", "parameter"), list(enumerate(name for _, name in _bad_calls())))
def test_wrong_shapes_raise_input_error_naming_the_parameter(index, parameter):
    call, _ = _bad_calls()[index]
    with pytest.raises(InputError) as info:
        call()
    assert info.value.parameter == parameter

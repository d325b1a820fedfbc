"""Per-reading uncertainty by the delta method: exact identities, then Monte Carlo.

Monte-Carlo tolerances: the standard deviation of ``z`` from ``R`` Gaussian draws has a
standard error of ``1 / sqrt(2 R)``; a variance estimated from ``R`` draws has a relative
standard error of ``sqrt(2 / R)``; a covariance entry ``C_ab`` has a standard error of
``sqrt((C_aa C_bb + C_ab^2) / R)``. Each assertion states the multiple it allows.
"""

from __future__ import annotations

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.models.linear_map import fit_map
from wavemeter.exceptions import InputError
from wavemeter.model.cone import cone_vectors, delay_phase_rad, wrap_phase_rad
from wavemeter.model.retrieval import cone_ml_phase_rad, source_power_ratio
from wavemeter.model.uncertainty import (
    calibration_frequency_variance_hz2,
    fit_parameter_covariance,
    ml_phase_gradient,
    phase_std_rad,
    pinv_phase_gradient,
    student_factor,
)

from .helpers import NOISE_W, POWER_W, random_test_frequencies

DEVICES = {
    "ideal": lambda ports: wm.Interferometer.ideal(ports),
    "table1": lambda ports: wm.Interferometer.table1(ports, seed=ports),
    "impaired": lambda ports: wm.Interferometer.table1(
        ports, seed=ports, symmetric_sigma=0.2, breaking_sigma=0.1, responsivity_sigma=0.4
    ),
}


def _port_noise(ports: int, unequal: bool) -> np.ndarray:
    """Per-port noise (W): equal, or in the pattern 1:3:1 repeated over the ports."""
    pattern = np.resize([1.0, 3.0, 1.0], ports) if unequal else np.ones(ports)
    return NOISE_W * pattern


def _readings(device, frequency_hz, power_w, noise_w, rng):
    """Simulated readings with per-port noise ``noise_w`` (n,)."""
    clean = device.powers(frequency_hz, power_w)
    return clean + rng.normal(0.0, 1.0, clean.shape) * noise_w


def _true_phase(device, frequency_hz):
    return wrap_phase_rad(delay_phase_rad(frequency_hz, device.center_hz, device.delay_s))


# ----------------------------------------------------------------------- exact identities
@pytest.mark.parametrize("ports", [3, 4, 5])
def test_ml_gradient_variance_is_the_cramer_rao_bound(ports):
    device = wm.Interferometer.table1(ports, seed=11)
    matrix = device.true_map()
    t = np.linspace(-np.pi, np.pi, 41)
    power = POWER_W * np.linspace(0.5, 1.5, t.size)
    for noise in (NOISE_W, _port_noise(ports, unequal=True)):
        gradient = ml_phase_gradient(matrix, t, power, noise)
        bound_hz = wm.crlb_frequency_std(matrix, t, power, noise, device.true_fsr_hz)
        std_hz = phase_std_rad(gradient, noise) * device.true_fsr_hz / (2 * np.pi)
        np.testing.assert_allclose(std_hz, bound_hz, rtol=1e-12)


def test_gradients_are_the_derivatives_of_the_estimators():
    """Central differences of the actual retrievals at noiseless readings (step 1e-4 sigma).

    At a noiseless reading the linearised ML gradient is the estimator's exact derivative;
    the truncation error of the differences is ~ (1e-4 sigma / P)^2, far below 1e-6.
    """
    device = wm.Interferometer.table1(4, seed=3, responsivity_sigma=0.3)
    matrix = POWER_W * device.true_map()
    noise = _port_noise(4, unequal=True)
    f = random_test_frequencies(device, 20, np.random.default_rng(0))
    readings = device.powers(f, POWER_W)
    t = _true_phase(device, f)
    inverse = np.linalg.pinv(matrix)
    step = 1e-4 * NOISE_W
    analytic = {
        "pinv": pinv_phase_gradient(readings, inverse),
        "ml": ml_phase_gradient(matrix, t, 1.0, noise),
    }
    estimators = {
        "pinv": lambda p: np.arctan2(p @ inverse[1], p @ inverse[0]),
        "ml": lambda p: cone_ml_phase_rad(p, matrix, noise_std_w=noise),
    }
    for name, estimate in estimators.items():
        numeric = np.empty_like(readings)
        for j in range(4):
            shift = np.zeros(4)
            shift[j] = step
            numeric[:, j] = wrap_phase_rad(estimate(readings + shift) - estimate(readings - shift))
        numeric /= 2 * step
        np.testing.assert_allclose(analytic[name], numeric, rtol=1e-6, atol=1e-6 / POWER_W)


def test_student_factor_is_the_spread_of_a_student_t():
    """z = N(0, 1) / sqrt(chi2_dof / dof), 400000 draws: std(z) to 4 standard errors.

    The variance of a Student t with 10 degrees of freedom has excess kurtosis 1, so one
    standard error of std(z) is sqrt(3 / 400000) / 2 = 0.14 %.
    """
    assert student_factor(3) == pytest.approx(np.sqrt(3.0), rel=1e-15)
    assert student_factor(4.0) == pytest.approx(np.sqrt(2.0), rel=1e-15)
    rng = np.random.default_rng(9)
    draws, dof = 400000, 10
    z = rng.normal(size=draws) / np.sqrt(rng.chisquare(dof, draws) / dof)
    assert np.std(z) == pytest.approx(student_factor(dof), rel=4 * np.sqrt(3 / draws) / 2)
    for bad in (2, 1.5, 0, -4, float("nan"), True, "10"):
        with pytest.raises(InputError) as info:
            student_factor(bad)
        assert info.value.parameter == "dof"


def test_bad_shapes_are_named():
    matrix = np.ones((3, 3))
    with pytest.raises(InputError, match="map_pinv must have shape"):
        pinv_phase_gradient(np.ones((5, 3)), np.ones((2, 3)))
    with pytest.raises(InputError, match="powers must have shape"):
        pinv_phase_gradient(np.ones((5, 4)), np.ones((3, 3)))
    with pytest.raises(InputError, match="noise_std_w must be one value or one per port"):
        ml_phase_gradient(matrix, [0.0], 1.0, [1.0, 2.0])
    with pytest.raises(InputError, match="noise_std_w"):
        phase_std_rad(np.ones((2, 3)), -1.0)
    with pytest.raises(InputError, match="covariance must have shape"):
        calibration_frequency_variance_hz2(
            np.ones((2, 3)), np.ones((2, 3)), [0, 0], 2e-11, np.eye(9)
        )
    with pytest.raises(InputError, match="delay_s"):
        calibration_frequency_variance_hz2(
            np.ones((2, 3)), np.ones((2, 3)), [0, 0], 0.0, np.eye(10)
        )
    same = np.tile(cone_vectors([0.3]), (5, 1))  # one phase: the map is not determined
    for derivative in (np.zeros((5, 3)), np.ones((5, 3))):
        with pytest.raises(InputError, match="does not determine"):
            fit_parameter_covariance(same, derivative, matrix, 1.0)


# ------------------------------------------------------------ z-scores of reading noise
@pytest.mark.slow
@pytest.mark.parametrize("unequal", [False, True], ids=["equal-noise", "noise-1:3:1"])
@pytest.mark.parametrize("kind", sorted(DEVICES))
@pytest.mark.parametrize("ports", [3, 4, 5])
def test_reading_noise_z_scores_have_unit_spread(ports, kind, unequal):
    """z = (t_hat - t) / std with the true map and noise: std(z) in [0.95, 1.05].

    40000 readings at powers 0.3-1.5 mW: one standard error of std(z) is 0.0035, so the
    band is 14 of them (the delta method's own error at this signal-to-noise is far less).
    """
    rng = np.random.default_rng(100 * ports + 10 * unequal + len(kind))
    device = DEVICES[kind](ports)
    noise = _port_noise(ports, unequal)
    f = random_test_frequencies(device, 40000, rng)
    power = POWER_W * rng.uniform(0.3, 1.5, f.size)
    readings = _readings(device, f, power, noise, rng)
    t = _true_phase(device, f)
    matrix = device.true_map()  # per watt of source power
    pinv_t = np.arctan2(readings @ np.linalg.pinv(matrix)[1], readings @ np.linalg.pinv(matrix)[0])
    pinv_std = phase_std_rad(pinv_phase_gradient(readings, np.linalg.pinv(matrix)), noise)
    ml_t = cone_ml_phase_rad(readings, matrix, noise_std_w=noise)
    ml_power = source_power_ratio(readings, matrix, ml_t, noise)
    ml_std = phase_std_rad(ml_phase_gradient(matrix, ml_t, ml_power, noise), noise)
    for estimate, std in ((pinv_t, pinv_std), (ml_t, ml_std)):
        z = wrap_phase_rad(estimate - t) / std
        assert 0.95 < np.std(z) < 1.05


# ------------------------------------------------------------------- the calibration fit
def _sweep_design(device, samples, power=None):
    """Object vectors, their delay derivative, and the true map (W) of a one-FSR sweep."""
    f = device.sweep_hz(samples)
    scale = np.ones(samples) if power is None else power
    t = delay_phase_rad(f, device.center_hz, device.delay_s)
    objects = cone_vectors(t, scale)
    tangent = np.stack([-np.sin(t), np.cos(t), np.zeros_like(t)], axis=-1)
    derivative = tangent * (2 * np.pi * (f - device.center_hz) * scale)[:, None]
    return f, objects, derivative, POWER_W * device.true_map()


def _fit_sweeps(powers, frequency_hz, center_hz, delay_s, weight, steps=5):
    """Least-squares map and delay of R sweeps at once: Gauss-Newton on the delay with the
    map profiled out (variable projection), started at ``delay_s``.

    ``powers`` (R, N, n); ``weight`` (n,) the per-port weights of the delay's cost
    ``sum_j w_j |residual_j|^2`` (the map's rows do not depend on them). The step uses the
    exact gradient of the profiled cost, so its fixed point is the least-squares optimum.
    Returns maps (R, n, 3), delays (R,) and the last delay steps (R,).
    """
    offset = 2 * np.pi * (frequency_hz - center_hz)

    def profile(delay):
        t = offset * delay[:, None]
        objects = cone_vectors(t)
        transposed = np.swapaxes(objects, 1, 2)
        gram = transposed @ objects
        maps_t = np.linalg.solve(gram, transposed @ powers)  # (R, 3, n)
        return t, objects, transposed, gram, maps_t

    delay = np.full(powers.shape[0], delay_s)
    for _ in range(steps):
        t, objects, transposed, gram, maps_t = profile(delay)
        residual = powers - objects @ maps_t
        tangent = np.stack([-np.sin(t), np.cos(t), np.zeros_like(t)], axis=-1)
        image = (tangent * offset[:, None]) @ maps_t
        off_model = image - objects @ np.linalg.solve(gram, transposed @ image)
        step = np.einsum("rnj,rnj,j->r", off_model, residual, weight) / np.einsum(
            "rnj,rnj,j->r", off_model, off_model, weight
        )
        delay = delay + step
    return np.swapaxes(profile(delay)[-1], 1, 2), delay, step


@pytest.mark.parametrize("affine", [False, True], ids=["map", "map+offsets"])
def test_covariance_matches_a_finite_difference_fisher_matrix(affine):
    """Dense central-difference Jacobian of the residual, F = J'WJ, inverted: 1e-8 relative.

    The map enters linearly (exact differences); the delay step of 1e-6 tau has a
    truncation error ~ (2 pi 1e-6)^2 and a rounding error ~ 1e-16 / 1e-6, both < 1e-9.
    Offsets need a varying source power (else the offset column equals the cone axis).
    """
    rng = np.random.default_rng(5)
    device = wm.Interferometer.table1(3, seed=5)
    power = rng.uniform(0.5, 1.5, 40) if affine else None
    f, objects, derivative, matrix = _sweep_design(device, 40, power)
    if affine:
        objects = np.column_stack([objects, np.ones(40)])
        derivative = np.column_stack([derivative, np.zeros(40)])
        matrix = np.column_stack([matrix, POWER_W * rng.uniform(0.01, 0.05, 3)])
    noise = _port_noise(3, unequal=True)
    covariance = fit_parameter_covariance(objects, derivative, matrix, noise)
    ports, k = matrix.shape
    scale = np.ones(40) if power is None else power

    def model(theta):
        a, tau = theta[:-1].reshape(ports, k), theta[-1]
        x = cone_vectors(delay_phase_rad(f, device.center_hz, tau), scale)
        x = np.column_stack([x, np.ones(40)]) if affine else x
        return ((x @ a.T) / noise).ravel()  # whitened model (residual = data - model)

    theta = np.append(matrix.ravel(), device.delay_s)
    jacobian = np.empty((40 * ports, theta.size))
    for i in range(theta.size):
        h = 1e-6 * abs(theta[i])
        up, down = theta.copy(), theta.copy()
        up[i] += h
        down[i] -= h
        jacobian[:, i] = (model(up) - model(down)) / (2 * h)
    expected = np.linalg.inv(jacobian.T @ jacobian)
    norm = np.sqrt(np.outer(np.diag(expected), np.diag(expected)))
    np.testing.assert_allclose(covariance / norm, expected / norm, rtol=0, atol=1e-8)


def test_covariance_matches_a_monte_carlo_of_the_fit():
    """400 least-squares fits of map and delay to one design with fresh noise each.

    Every entry of the sample covariance lies within 4.5 of its standard errors of the
    predicted one (55 entries: a false alarm has probability ~4e-4); the delay's variance
    within 4.5 x sqrt(2/400) = 32 % relative.
    """
    rng = np.random.default_rng(6)
    device = wm.Interferometer.table1(3, seed=6)
    f, objects, derivative, matrix = _sweep_design(device, 64)
    noise = _port_noise(3, unequal=True)
    covariance = fit_parameter_covariance(objects, derivative, matrix, noise)
    repeats = 400
    clean = objects @ matrix.T
    sweeps = clean + rng.normal(0.0, 1.0, (repeats, *clean.shape)) * noise
    maps, delays, last = _fit_sweeps(sweeps, f, device.center_hz, device.delay_s, 1 / noise**2)
    assert np.max(np.abs(last)) < 1e-6 * np.sqrt(covariance[-1, -1])  # converged
    # the helper's map is the library's least-squares map at its delay
    at_delay = cone_vectors(delay_phase_rad(f, device.center_hz, delays[0]))
    np.testing.assert_allclose(maps[0], fit_map(at_delay, sweeps[0]), rtol=1e-9)
    theta = np.column_stack([maps.reshape(repeats, -1), delays])
    sample = np.cov(theta, rowvar=False)
    variance = np.diag(covariance)
    stderr = np.sqrt((np.outer(variance, variance) + covariance**2) / repeats)
    assert np.all(np.abs(sample - covariance) < 4.5 * stderr)
    assert sample[-1, -1] / covariance[-1, -1] == pytest.approx(1.0, abs=4.5 * np.sqrt(2 / 400))


@pytest.mark.slow
@pytest.mark.parametrize("retrieval", ["pinv", "ml"])
@pytest.mark.parametrize("sweep_samples", [8, 200])
def test_calibration_variance_of_a_reading_over_many_calibrations(sweep_samples, retrieval):
    """2000 calibrations (map and delay fitted) of one device, and five test readings.

    * a fixed noisy reading: its frequency varies only with the calibration; the sample
      variance matches calibration_frequency_variance_hz2 within 4.5 sqrt(2/2000) = 14 %;
    * a fresh reading at the same frequency each time: the variance is the calibration's
      plus the reading noise's, within the same 14 %.
    Readings near the ends of the FSR carry a large share from the delay: without it the
    prediction would be off by more than the tolerance (checked, so the term is tested).
    """
    rng = np.random.default_rng(sweep_samples + len(retrieval))
    device = wm.Interferometer.table1(3, seed=8)
    f, objects, derivative, matrix = _sweep_design(device, sweep_samples)
    noise = np.full(3, NOISE_W)
    covariance = fit_parameter_covariance(objects, derivative, matrix, noise)
    repeats = 2000
    clean = objects @ matrix.T
    sweeps = clean + rng.normal(0.0, NOISE_W, (repeats, *clean.shape))
    maps, delays, last = _fit_sweeps(sweeps, f, device.center_hz, device.delay_s, 1 / noise**2)
    assert np.max(np.abs(last)) < 1e-6 * np.sqrt(covariance[-1, -1])  # converged

    test_hz = device.center_hz + device.true_fsr_hz * np.array([-0.45, -0.2, 0.0, 0.25, 0.45])
    t = _true_phase(device, test_hz)
    fixed = _readings(device, test_hz, POWER_W, noise, rng)
    fresh = _readings(device, np.tile(test_hz, repeats), POWER_W, noise, rng)

    def phase(readings, a):
        if retrieval == "ml":
            return cone_ml_phase_rad(readings, a)
        inverse = np.linalg.pinv(a)
        return np.arctan2(readings @ inverse[1], readings @ inverse[0])

    frequency_hz = np.empty((repeats, 2, 5))  # calibration, (fixed, fresh) reading, frequency
    for r in range(repeats):
        both = np.vstack([fixed, fresh[5 * r : 5 * r + 5]])
        to_hz = 1 / (2 * np.pi * delays[r])
        frequency_hz[r] = (device.center_hz + phase(both, maps[r]) * to_hz).reshape(2, 5)
    fixed_var, fresh_var = np.var(frequency_hz, axis=0)

    if retrieval == "ml":
        gradient = ml_phase_gradient(matrix, t, 1.0, noise)
    else:
        gradient = pinv_phase_gradient(fixed, np.linalg.pinv(matrix))
    objects_estimate = cone_vectors(t)
    predicted = calibration_frequency_variance_hz2(
        gradient, objects_estimate, t, device.delay_s, covariance
    )
    noise_part = (phase_std_rad(gradient, noise) / (2 * np.pi * device.delay_s)) ** 2
    tolerance = 4.5 * np.sqrt(2 / repeats)
    np.testing.assert_allclose(fixed_var / predicted, 1.0, atol=tolerance)
    np.testing.assert_allclose(fresh_var / (predicted + noise_part), 1.0, atol=tolerance)
    without_delay = covariance.copy()
    without_delay[-1, :] = without_delay[:, -1] = 0.0
    map_only = calibration_frequency_variance_hz2(
        gradient, objects_estimate, t, device.delay_s, without_delay
    )
    assert np.max(np.abs(map_only / predicted - 1)) > 2 * tolerance

"""The fused retrieval kernels: numba and numpy paths against each other, against the
steps taken one by one, and against the refusals of ``check_powers``."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

import wavemeter as wm
from wavemeter.calibration.models.learned_fit import retrieve_phase_rad
from wavemeter.model import kernels, numba_kernel
from wavemeter.model.cone import cone_vectors, phase_to_frequency_hz, wrap_phase_rad
from wavemeter.model.retrieval import cone_ml_phase_rad
from wavemeter.validation import check_powers

from .helpers import NOISE_W, POWER_W, random_test_frequencies

#: phase agreement of two roundings of the same retrieval (rad): the products round at
#: ~1e-16 of the quadratures, times the map's condition number (< 10 for Table 1 devices);
#: the maximum likelihood's root stops within TOLERANCE = 1e-13 (relative) of the root.
#: 1e-12 leaves a margin over both and still catches any wrong step
PHASE_TOL_RAD = 1e-12
#: readings the numba path takes without being asked, for either retrieval
LARGE = 2 * max(kernels.NUMBA_MIN_READINGS.values())
RETRIEVALS = ("pinv", "ml")


@pytest.fixture(autouse=True)
def fresh_backend_choice():
    """Each test finds numba (or not) afresh, and leaves no choice behind."""
    numba_kernel.numba_module.cache_clear()
    yield
    numba_kernel.numba_module.cache_clear()


def needs(backend: str) -> None:
    if backend == "numba":
        pytest.importorskip("numba")
        if numba_kernel.kernel_backend() != "numba":
            pytest.skip(f"{numba_kernel.NO_NUMBA_VARIABLE} is set")


def phase_gap_rad(a, b) -> np.ndarray:
    return np.abs(wrap_phase_rad(np.asarray(a) - np.asarray(b)))


def frequency_gap_hz(a, b, fsr_hz: float) -> np.ndarray:
    """|a - b| modulo the FSR (a reading on the branch cut may land on either side)."""
    gap = np.mod(np.asarray(a) - np.asarray(b), fsr_hz)
    return np.minimum(gap, fsr_hz - gap)


def frequency_tol_hz(frequency_hz, fsr_hz: float) -> np.ndarray:
    """The phase tolerance in Hz plus the rounding of ``f0 + t FSR / 2 pi`` itself."""
    return PHASE_TOL_RAD * fsr_hz / (2 * np.pi) + 4 * np.spacing(np.abs(frequency_hz))


def fitted(ports: int, seed: int, *, retrieval: str = "pinv", dark_w=None):
    """A Calibrator of a Table 1 device, the device and a generator for test readings."""
    rng = np.random.default_rng(seed)
    device = wm.Interferometer.table1(ports, seed=seed)
    sweep_hz = device.sweep_hz(400)
    offset = 0.0 if dark_w is None else dark_w
    sweep = device.powers(sweep_hz, POWER_W, NOISE_W, rng) + offset
    cal = wm.Calibrator(fsr_hz=50e9, retrieval=retrieval).fit(sweep, sweep_hz, dark_w=dark_w)
    return cal, device, rng


def readings_near_branch_cut(cal, rng, samples: int) -> np.ndarray:
    """Noiseless readings of the map (no offsets) at phases 1e-15..1e-9 rad from +-pi."""
    steps = 10.0 ** rng.uniform(-15, -9, samples) * rng.choice([-1.0, 1.0], samples)
    return cone_vectors(np.pi + steps, POWER_W) @ cal.map_.T


def sample_readings(cal, device, rng, samples: int, offset_w) -> np.ndarray:
    """Readings with Table 1 noise, at the branch cut, and off the model (50x the noise)."""
    hz = random_test_frequencies(device, samples, rng)
    far = device.powers(hz, POWER_W, 50 * NOISE_W, rng)
    return np.vstack(
        [
            device.powers(hz, POWER_W, NOISE_W, rng),
            readings_near_branch_cut(cal, rng, samples),
            far,
        ]
    ) + np.asarray(offset_w)


def fused_phase(retrieval: str, cal, readings, **options) -> np.ndarray:
    if retrieval == "ml":
        noise = cal.port_noise_std_w_
        return kernels.fused_ml_phase_rad(readings, cal.map_, noise_std_w=noise, **options)
    return kernels.fused_pinv_phase_rad(readings, cal.map_pinv_, **options)


def fused_frequency(retrieval: str, cal, readings, **options) -> np.ndarray:
    args = (cal.center_hz_, cal.fsr_hz_)
    if retrieval == "ml":
        noise = cal.port_noise_std_w_
        return kernels.fused_ml_frequency_hz(
            readings, cal.map_, *args, noise_std_w=noise, **options
        )
    return kernels.fused_pinv_frequency_hz(readings, cal.map_pinv_, *args, **options)


# ---------------------------------------------------------------- the arctangent
@pytest.mark.parametrize("backend", kernels.BACKENDS)
def test_arctangent_within_three_ulp_of_numpy(backend):
    """With an identity inverse the phase is atan2(p_2, p_1): every magnitude from 1e-150
    to 1e150, both signs, the reduction boundary (ratio 0.66), the diagonals, the smallest
    subnormals (where 0.66 times a quadrature rounds up to itself) and the axes (the map
    product turns -0 into +0, in numpy as in the kernel)."""
    needs(backend)
    rng = np.random.default_rng(3)
    spread = 10.0 ** rng.uniform(-150, 150, (20000, 2)) * rng.choice([-1.0, 1.0], (20000, 2))
    boundary = np.column_stack([np.ones(4000), rng.uniform(0.65, 0.67, 4000)])
    boundary *= rng.choice([-1.0, 1.0], (4000, 2))
    diagonal = np.array([[1.0, 1.0], [-1.0, 1.0], [1.0, -1.0], [-1.0, -1.0], [3.0, 2.0]])
    subnormal = np.array([[5e-324, 5e-324], [-5e-324, 5e-324], [1.5e-323, -1e-323]])
    axes = np.array([[0.0, 0.0], [0.0, 5.0], [0.0, -5.0], [2.0, 0.0], [-2.0, 0.0]])
    xy = np.vstack([spread, boundary, diagonal, subnormal, axes])
    readings = np.column_stack([xy, np.ones(xy.shape[0])])
    phase = kernels.fused_pinv_phase_rad(readings, np.eye(3), backend=backend)
    expected = np.arctan2(xy[:, 1], xy[:, 0])
    # numba's arctangent is within 1.5 ulp of the exact value (1e7 inputs), numpy's within 1
    assert np.all(np.abs(phase - expected) <= 3 * np.spacing(np.abs(expected)))
    # on the axes: exactly numpy's 0, +-pi/2 and pi
    np.testing.assert_array_equal(phase[-5:], expected[-5:])


# ---------------------------------------------------------------- both paths agree
@pytest.mark.parametrize("retrieval", RETRIEVALS)
@pytest.mark.parametrize("ports", [3, 4])
@pytest.mark.parametrize("offsets", [False, True], ids=["no-offsets", "offsets"])
def test_numba_and_numpy_paths_agree(retrieval, ports, offsets):
    needs("numba")
    cal, device, rng = fitted(ports, seed=ports + 10, retrieval=retrieval)
    offset = np.linspace(2e-6, 5e-6, ports) if offsets else np.zeros(ports)
    readings = sample_readings(cal, device, rng, 3000, offset)
    found = {
        backend: fused_frequency(retrieval, cal, readings, offset_w=offset, backend=backend)
        for backend in kernels.BACKENDS
    }
    gap = frequency_gap_hz(found["numba"], found["numpy"], cal.fsr_hz_)
    assert np.all(gap <= frequency_tol_hz(found["numpy"], cal.fsr_hz_))
    phases = [
        fused_phase(retrieval, cal, readings, offset_w=offset, backend=backend)
        for backend in kernels.BACKENDS
    ]
    assert phase_gap_rad(*phases).max() <= PHASE_TOL_RAD
    # readings on both sides of the branch cut: the wrap is exercised, not avoided
    cut = phases[0][3000:6000]
    assert (cut > 3.14).any() and (cut < -3.14).any()


@pytest.mark.parametrize("retrieval", RETRIEVALS)
def test_shared_and_single_thread_calls_give_the_same_bits(monkeypatch, retrieval):
    """Large batches are shared among threads in parts (the last one short here), smaller
    ones run on this thread alone: the same numbers, whichever thread took which part."""
    needs("numba")
    import numba

    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 2)  # shared even on one core
    cal, device, rng = fitted(3, seed=21, retrieval=retrieval)
    readings = sample_readings(cal, device, rng, 3 * numba_kernel.BLOCK_ROWS + 5, np.zeros(3))
    assert readings.shape[0] > 2 * numba_kernel.BLOCK_ROWS  # several parts
    found = {}
    for shared, threshold in ((False, readings.shape[0] + 1), (True, 1)):
        monkeypatch.setitem(kernels.PARALLEL_MIN_READINGS, retrieval, threshold)
        found[shared] = fused_frequency(retrieval, cal, readings, backend="numba")
    np.testing.assert_array_equal(found[True], found[False])


@pytest.mark.parametrize("retrieval", RETRIEVALS)
@pytest.mark.parametrize("backend", kernels.BACKENDS)
@pytest.mark.parametrize(
    "bad", [np.nan, np.inf, -np.inf, "dark"], ids=["nan", "inf", "-inf", "dark"]
)
def test_refusals_are_those_of_check_powers(retrieval, backend, bad):
    needs(backend)
    cal, device, rng = fitted(3, seed=5, retrieval=retrieval)
    readings = device.powers(random_test_frequencies(device, 300, rng), POWER_W, 0.0, rng)
    if bad == "dark":
        readings[[7, 250]] = [[-1e-6, 0.0, 0.5e-6], [0.0, 0.0, 0.0]]
    else:
        readings[[3, 120, 121], [0, 2, 1]] = bad
    with pytest.raises(wm.InputError) as expected:
        check_powers(readings, ports=3)
    with pytest.raises(wm.InputError) as refused:
        fused_frequency(retrieval, cal, readings, check=True, backend=backend)
    assert str(refused.value) == str(expected.value)


@pytest.mark.parametrize("retrieval", RETRIEVALS)
@pytest.mark.parametrize("backend", kernels.BACKENDS)
def test_unchecked_readings_pass_and_no_readings_are_refused(retrieval, backend):
    needs(backend)
    cal, device, rng = fitted(3, seed=6, retrieval=retrieval)
    readings = device.powers(random_test_frequencies(device, 300, rng), POWER_W, 0.0, rng)
    readings[5] = [np.nan, 0.0, 0.0]
    readings[6] = 0.0
    phase = fused_phase(retrieval, cal, readings, check=False, backend=backend)
    assert np.isfinite(np.delete(phase, [5, 6])).all()
    with pytest.raises(wm.InputError, match="need at least 1 samples, got 0"):
        fused_frequency(retrieval, cal, np.empty((0, 3)), check=True, backend=backend)


@pytest.mark.parametrize("shared", [False, True], ids=["one thread", "shared"])
def test_numpy_parts_and_products_join_seamlessly(monkeypatch, shared):
    """Readings over several parts of the numpy path, each over several matrix products (the
    last ones short), on this thread alone or shared among threads: every part's phases,
    offsets and check, and the same bits either way."""
    monkeypatch.setattr(kernels, "_cores", lambda: 2)  # shared even on one core
    monkeypatch.setattr(kernels, "NUMPY_PART_ROWS", 5000)
    monkeypatch.setattr(kernels, "NUMPY_PRODUCT_SIZE", 3 * 3 * 1500)
    threshold = 1 if shared else 10**9
    monkeypatch.setattr(kernels, "NUMPY_PARALLEL_MIN_READINGS", threshold)
    cal, device, rng = fitted(3, seed=9)
    samples = 4 * 5000 + 7
    offset = np.array([1e-6, 2e-6, 3e-6])
    readings = device.powers(random_test_frequencies(device, samples, rng), POWER_W, 0.0, rng)
    readings += offset
    arguments = (readings, cal.map_pinv_)
    options = {"offset_w": offset, "check": True, "backend": "numpy"}
    phase = kernels.fused_pinv_phase_rad(*arguments, **options)
    expected = retrieve_phase_rad(readings - offset, cal.map_pinv_)
    assert phase_gap_rad(phase, expected).max() <= PHASE_TOL_RAD
    monkeypatch.setattr(kernels, "NUMPY_PARALLEL_MIN_READINGS", 10**9)
    np.testing.assert_array_equal(phase, kernels.fused_pinv_phase_rad(*arguments, **options))
    readings[samples - 2, 0] = np.inf  # in the last, short part
    with pytest.raises(wm.InputError, match=rf"NaN or inf in rows \[{samples - 2}\]"):
        kernels.fused_pinv_phase_rad(readings, cal.map_pinv_, check=True, backend="numpy")


def test_a_short_call_on_many_cores_wakes_no_more_helpers_than_parts(monkeypatch):
    """3 parts with 7 workers: this thread and 2 helpers, not 7 (each costs a wake-up)."""
    submitted = []
    pool = kernels._workers(os.getpid(), 1)

    class Recording:
        def submit(self, task):
            submitted.append(task)
            return pool.submit(task)

    monkeypatch.setattr(kernels, "_workers", lambda pid, count: Recording())

    def double(readings, out, start, stop) -> int:
        out[start:stop] = 2.0 * readings[start:stop]
        return 0

    readings, out = np.arange(2500.0), np.empty(2500)
    assert kernels._shared(double, readings, (), out, 1000, 7) == 0
    assert len(submitted) == 2
    np.testing.assert_array_equal(out, 2.0 * readings)


def test_bad_shapes_are_refused():
    with pytest.raises(wm.InputError, match=r"map_pinv must have shape \(3, n\)"):
        kernels.fused_pinv_phase_rad(np.ones((4, 3)), np.ones((2, 3)))
    with pytest.raises(wm.InputError, match=r"map_ must have shape \(n, 3\)"):
        kernels.fused_ml_phase_rad(np.ones((4, 3)), np.ones((3, 2)))
    with pytest.raises(wm.InputError, match="port powers have 4 ports but the calibration has 3"):
        kernels.fused_pinv_phase_rad(np.ones((4, 4)), np.eye(3))
    with pytest.raises(wm.InputError, match="offset_w must hold 3 values"):
        kernels.fused_pinv_phase_rad(np.ones((4, 3)), np.eye(3), offset_w=[1.0, 2.0])
    with pytest.raises(wm.InputError, match="backend must be one of"):
        kernels.fused_pinv_phase_rad(np.ones((4, 3)), np.eye(3), backend="cuda")


# ---------------------------------------------------------------- choosing the path
def test_no_numba_variable_keeps_the_numpy_path(monkeypatch):
    monkeypatch.setenv(numba_kernel.NO_NUMBA_VARIABLE, "1")
    assert numba_kernel.kernel_backend() == "numpy"
    monkeypatch.setattr(kernels, "_numba_path", None)  # any call to it would fail
    readings = np.tile([2.0, 1.0, 1.0], (LARGE, 1))
    np.testing.assert_array_equal(
        kernels.fused_pinv_phase_rad(readings, np.eye(3)), np.arctan2(1.0, 2.0)
    )
    with pytest.raises(wm.InputError, match="backend 'numba' needs numba"):
        kernels.fused_pinv_phase_rad(readings, np.eye(3), backend="numba")


@pytest.mark.parametrize("retrieval", RETRIEVALS)
def test_numba_takes_large_batches_only(monkeypatch, retrieval):
    needs("numba")
    monkeypatch.setenv(numba_kernel.NO_NUMBA_VARIABLE, "0")
    assert numba_kernel.kernel_backend() == "numba"
    cal, device, rng = fitted(3, seed=7, retrieval=retrieval)
    calls = []
    numba_path = kernels._numba_path

    def spy(ml, readings, *args):
        calls.append((ml, readings.shape[0]))
        return numba_path(ml, readings, *args)

    monkeypatch.setattr(kernels, "_numba_path", spy)
    least = kernels.NUMBA_MIN_READINGS[retrieval]
    readings = device.powers(random_test_frequencies(device, least, rng), POWER_W, NOISE_W, rng)
    for samples in (1, least - 1, least):
        fused_phase(retrieval, cal, readings[:samples])
    assert calls == [(retrieval == "ml", least)]


@pytest.mark.slow
def test_importing_wavemeter_and_small_batches_leave_numba_unimported():
    code = (
        "import sys, numpy as np, wavemeter as wm\n"
        "from wavemeter.model import kernels\n"
        "kernels.fused_pinv_phase_rad(np.ones((100, 3)), np.eye(3))\n"
        "print('numba' in sys.modules)\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "False"


@pytest.mark.slow
def test_the_disk_cache_keeps_a_kernel_per_setting(tmp_path):
    """numba's cache keys a kernel by its code and free variables only: a kernel built with
    another setting (here the most Newton steps) must be compiled anew, not loaded."""
    pytest.importorskip("numba")
    code = (
        "import sys, numpy as np\n"
        "from wavemeter.model import kernels, numba_kernel\n"
        "numba_kernel.MAX_STEPS = int(sys.argv[1])\n"
        "rng = np.random.default_rng(1)\n"
        "readings = rng.uniform(1.0, 2.0, (kernels.NUMBA_MIN_READINGS['ml'], 3))\n"
        "phase = kernels.fused_ml_phase_rad(readings, rng.normal(size=(3, 3)), backend='numba')\n"
        "print(phase[:20].tolist())\n"
    )
    env = {k: v for k, v in os.environ.items() if k != numba_kernel.NO_NUMBA_VARIABLE}
    env["NUMBA_CACHE_DIR"] = str(tmp_path)

    def phases(max_steps: int) -> str:
        command = [sys.executable, "-c", code, str(max_steps)]
        return subprocess.run(command, capture_output=True, text=True, check=True, env=env).stdout

    converged = phases(numba_kernel.MAX_STEPS)
    assert phases(1) != converged  # one step: not the cached kernel of MAX_STEPS steps
    assert phases(numba_kernel.MAX_STEPS) == converged


@pytest.mark.slow
@pytest.mark.skipif(not hasattr(os, "register_at_fork"), reason="no fork on this platform")
def test_a_process_forked_after_a_kernel_ran_runs_the_kernels_too():
    """A child forked after its parent shared a call among threads (threads a child does
    not inherit) runs the kernels too, to the same numbers: no OpenMP, which kills such a
    child at its first parallel loop, and no wait for a thread that is not there."""
    pytest.importorskip("numba")
    code = (
        "import multiprocessing, numpy as np\n"
        "from wavemeter.model import kernels, numba_kernel\n"
        "readings = np.tile([2.0, 1.0, 1.0], (kernels.PARALLEL_MIN_READINGS['pinv'], 1))\n"
        "def phase(_):\n"
        "    found = kernels.fused_pinv_phase_rad(readings, np.eye(3), backend='numba')\n"
        "    return numba_kernel.kernel_backend(), float(np.ptp(found)), float(found[0])\n"
        "if __name__ == '__main__':\n"
        "    phase(0)\n"
        "    with multiprocessing.get_context('fork').Pool(1) as pool:\n"
        "        print(*pool.map_async(phase, [0]).get(timeout=60)[0])\n"
    )
    env = {k: v for k, v in os.environ.items() if k != numba_kernel.NO_NUMBA_VARIABLE}
    env["NUMBA_NUM_THREADS"] = "2"  # a shared call even on a single core
    run = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
        env=env,
    )
    backend, spread, phase = run.stdout.split()
    assert backend == "numba" and float(spread) == 0.0
    assert float(phase) == pytest.approx(np.arctan2(1.0, 2.0), rel=4 * np.finfo(float).eps)


# ---------------------------------------------------------------- the calibrator
def steps_one_by_one(cal, readings, offset_w) -> np.ndarray:
    """The phase as predict found it before the kernels: offsets off, then the retrieval."""
    light = readings - offset_w
    if cal.retrieval == "ml":
        return cone_ml_phase_rad(light, cal.map_, noise_std_w=cal.port_noise_std_w_)
    return retrieve_phase_rad(light, cal.map_pinv_)


@pytest.mark.slow
@pytest.mark.parametrize("retrieval", RETRIEVALS)
@pytest.mark.parametrize("ports", [3, 4])
@pytest.mark.parametrize("no_numba", ["0", "1"], ids=["auto", "numpy"])
def test_calibrator_predict_equals_the_steps_one_by_one(monkeypatch, retrieval, ports, no_numba):
    if no_numba == "0":
        needs("numba")
    monkeypatch.setenv(numba_kernel.NO_NUMBA_VARIABLE, no_numba)
    dark = np.linspace(1e-6, 4e-6, ports)
    cal, device, rng = fitted(ports, seed=ports + 20, retrieval=retrieval, dark_w=dark)
    for samples in (1, 50, LARGE // 3):  # the small path and, with numba, the large one
        readings = sample_readings(cal, device, rng, samples, dark)
        phase = steps_one_by_one(cal, readings, dark)
        expected = phase_to_frequency_hz(phase, cal.center_hz_, cal.fsr_hz_)
        predicted = cal.predict(readings)
        gap = frequency_gap_hz(predicted, expected, cal.fsr_hz_)
        assert np.all(gap <= frequency_tol_hz(expected, cal.fsr_hz_))
        assert phase_gap_rad(cal.phase(readings), phase).max() <= PHASE_TOL_RAD
    # one reading given as a vector
    one = cal.predict(readings[0])
    assert one.shape == (1,)
    assert frequency_gap_hz(one, predicted[0], cal.fsr_hz_) <= frequency_tol_hz(one, cal.fsr_hz_)
    # a reading that cannot be read gets NaN and costs no other; errors="raise" refuses it
    # with check_powers' message; the per-reading inputs are checked as before
    readings[2, 1] = np.nan
    coerced = cal.predict(readings)
    assert np.isnan(coerced[2]) and not np.isnan(np.delete(coerced, 2)).any()
    kept, before = np.delete(coerced, 2), np.delete(predicted, 2)
    assert np.all(
        frequency_gap_hz(kept, before, cal.fsr_hz_) <= frequency_tol_hz(kept, cal.fsr_hz_)
    )
    with pytest.raises(wm.InputError, match=r"NaN or inf in rows \[2\]"):
        cal.predict(readings, errors="raise")
    with pytest.raises(wm.InputError, match="coarse_hz must be one value or one per reading"):
        cal.predict(np.full((3, ports), 1e-3), coarse_hz=[1.0, 2.0])

"""Fused phase retrieval: check, offsets, map product, phase and scale in one pass.

:func:`fused_pinv_frequency_hz`, :func:`fused_ml_frequency_hz` (and their ``_phase_rad``
twins) retrieve a block of readings by the pseudo-inverse or the cone maximum likelihood
in one pass per reading instead of numpy's many, with no temporaries:

* **numba** (the optional extra ``fast``): compiled per port count
  (:mod:`wavemeter.model.numba_kernel`; :func:`~wavemeter.model.numba_kernel.kernel_backend`
  says which path large batches take), shared among threads in ``PARALLEL_PARTS`` parts;
* **numpy** (the fallback, and batches below ``NUMBA_MIN_READINGS``): parts of
  ``NUMPY_PART_ROWS`` readings, shared among threads from ``NUMPY_PARALLEL_MIN_READINGS``.

Both paths give the unfused steps to rounding (1e-12 rad), and refuse readings through
:func:`~wavemeter.validation.check_powers` with its messages. Theory (the design, the
timings): the docs' large-sweeps page (``docs/theory/large-sweeps.rst``, "Fused retrieval
kernels").
"""

from __future__ import annotations

import functools
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..exceptions import InputError
from ..validation import check_choice, check_powers, reading_array
from .numba_kernel import BLOCK_ROWS, NO_NUMBA_VARIABLE, build_kernel, numba_module
from .retrieval import cone_frame, cone_ml_phase_rad, noise_weighted_map

__all__ = [
    "BACKENDS",
    "NUMBA_MIN_READINGS",
    "NUMPY_PARALLEL_MIN_READINGS",
    "NUMPY_PART_ROWS",
    "NUMPY_PRODUCT_SIZE",
    "fused_ml_frequency_hz",
    "fused_ml_phase_rad",
    "fused_pinv_frequency_hz",
    "fused_pinv_phase_rad",
]

#: fewest readings the numba kernels take, by retrieval. The warm kernels win from 100
#: readings on (pinv 5 us vs numpy 15 us, ml 43 vs 205 us), but a batch that takes numba
#: first imports it and loads the kernel (0.3 s; 0.8-1.6 s to compile on a first run).
#: Below these sizes numpy takes under ~0.1 ms (pinv) and ~0.4 ms (ml): no gain worth it
NUMBA_MIN_READINGS = {"pinv": 10_000, "ml": 1_000}
#: readings from which a numba call is shared among threads (fewer: this thread alone). A
#: worker thread takes tens of microseconds to wake (measured crossover: pinv about 1e5
#: readings, ml about 1e4). Shared, a large call takes 0.55x one thread's time (pinv; ml
#: 0.55-0.6x) on a free machine and 5-25% more while another process keeps a core busy
PARALLEL_MIN_READINGS = {"pinv": 1 << 17, "ml": 1 << 14}
#: parts a shared call is cut into (whole blocks, at least half the readings above): this
#: thread and the workers take the next part whenever they are free, so a thread the system
#: does not schedule for a while (another process on its core) holds back at most one part.
#: numba's own parallel loops split the work in equal shares up front and wait for the
#: slowest: 3 to 10 times one thread's time, measured here while other processes kept the
#: cores busy
PARALLEL_PARTS = 16
#: largest matrix product of the numpy path, m n k: OpenBLAS threads larger ones (its
#: threshold, 4 x 65536), and its threads, spinning on after the product, would take the
#: cores from the threads sharing the parts below (a 2-core call took 2x the time)
NUMPY_PRODUCT_SIZE = 1 << 18
#: readings per part of the numpy path that threads share: each of its numpy calls must
#: take well over the ~30 us a waiting thread needs to wake and take the GIL, or the
#: thread that holds it takes every part (1e6 readings in parts of 8192 took longer shared
#: than on one thread)
NUMPY_PART_ROWS = 1 << 16
#: fewest readings the numpy path shares among threads
NUMPY_PARALLEL_MIN_READINGS = 1 << 15
#: ``backend`` values: None picks numba for large batches when it is there
BACKENDS = ("numba", "numpy")


@functools.cache
def _workers(pid: int, count: int) -> ThreadPoolExecutor:
    """``count`` worker threads of process ``pid`` (a forked child has none of its parent's
    threads: it starts its own pool)."""
    return ThreadPoolExecutor(count, thread_name_prefix=f"wavemeter-kernel-{pid}")


def _part_rows(rows: int, retrieval: str) -> int:
    """Readings per part of a call: all of them below ``PARALLEL_MIN_READINGS``, else a
    ``PARALLEL_PARTS``-th of them but at least half that threshold (each part pays for
    handing work to a thread), in whole blocks."""
    least = PARALLEL_MIN_READINGS[retrieval]
    if rows < least:
        return rows
    part = max(-(-rows // PARALLEL_PARTS), least // 2)
    return -(-part // BLOCK_ROWS) * BLOCK_ROWS


def _shared(kernel, readings, arguments, out, part: int, workers: int) -> int:
    """``kernel`` over every reading in parts of ``part`` readings, taken by this thread
    and ``workers`` worker threads as they come free; the number of refused readings."""
    rows = readings.shape[0]
    if part >= rows or workers < 1:
        return kernel(readings, *arguments, out, 0, rows)
    # one iterator for every thread: each part is taken once (next() holds the GIL)
    parts = iter(range(0, rows, part))

    def take_parts() -> int:
        return sum(
            kernel(readings, *arguments, out, start, min(start + part, rows)) for start in parts
        )

    pool = _workers(os.getpid(), workers)
    # no more helpers than parts left for them (a machine of many cores, a short call)
    helpers = [pool.submit(take_parts) for _ in range(min(workers, -(-rows // part) - 1))]
    refused = take_parts()
    # a helper not started yet (its thread not scheduled) has nothing left to do
    return refused + sum(helper.result() for helper in helpers if not helper.cancel())


def _numba_path(ml, readings, matrices, offset_w, origin, scale) -> tuple[np.ndarray, bool]:
    out = np.empty(readings.shape[0])
    weights, to_objects, kappa = matrices
    arguments = (
        tuple(offset_w.tolist()),
        tuple(tuple(coefficients) for coefficients in weights.tolist()),
        to_objects,
        kappa,
        origin,
        scale,
    )
    kernel = build_kernel(readings.shape[1], ml)
    part = _part_rows(readings.shape[0], "ml" if ml else "pinv")
    workers = numba_module().config.NUMBA_NUM_THREADS - 1
    refused = _shared(kernel, np.ascontiguousarray(readings), arguments, out, part, workers)
    return out, refused == 0 and out.size > 0


def _cores() -> int:
    """Cores this process may run on."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def _numpy_pinv_part(readings, weights, shift, origin, scale, check, out, start, stop) -> int:
    """The numpy path over readings ``start`` to ``stop``, ``NUMPY_PART_ROWS`` at a time:
    their product by ``weights`` (both quadratures, and to ``check`` the total power) in
    contiguous rows, in products of at most ``NUMPY_PRODUCT_SIZE``, then ``arctan2``, scale
    and shift in place; 1 if a reading there is NaN, inf or dark, else 0."""
    buffer = np.empty((weights.shape[0], min(stop - start, NUMPY_PART_ROWS)))
    product_rows = max(NUMPY_PRODUCT_SIZE // weights.size, 1)
    refused = 0
    for part_start in range(start, stop, NUMPY_PART_ROWS):
        part_stop = min(part_start + NUMPY_PART_ROWS, stop)
        rows = buffer[:, : part_stop - part_start]
        for first in range(part_start, part_stop, product_rows):
            last = min(first + product_rows, part_stop)
            product = rows[:, first - part_start : last - part_start]
            with np.errstate(invalid="ignore"):  # inf readings: refused below, or flagged
                np.matmul(weights, readings[first:last].T, out=product)
        if shift is not None:
            rows[:2] -= shift
        phase = out[part_start:part_stop]
        np.arctan2(rows[1], rows[0], out=phase)
        if scale != 1.0:
            phase *= scale
        if origin != 0.0:
            phase += origin
        if check and not refused:
            total = rows[2]
            refused = int(not (total.min() > 0.0 and total.max() < np.inf))
    return refused


def _numpy_pinv(readings, inverse, offset_w, origin, scale, check) -> tuple[np.ndarray, bool]:
    weights = inverse[:2]
    stacked = np.vstack([weights, np.ones(readings.shape[1])]) if check else weights
    shift = (weights @ offset_w)[:, None] if offset_w.any() else None
    samples = readings.shape[0]
    out = np.empty(samples)
    cores = _cores()
    part = samples
    if samples >= NUMPY_PARALLEL_MIN_READINGS:  # a share per core, up to a part's size
        part = min(NUMPY_PART_ROWS, -(-samples // cores))
    arguments = (stacked, shift, origin, scale, check)
    refused = _shared(_numpy_pinv_part, readings, arguments, out, part, cores - 1)
    return out, refused == 0 and samples > 0


def _numpy_ml(readings, map_, noise_std_w, offset_w, origin, scale, check):
    if check:
        check_powers(readings, ports=readings.shape[1])
    light = readings - offset_w if offset_w.any() else readings
    return origin + cone_ml_phase_rad(light, map_, noise_std_w=noise_std_w) * scale, True


def _use_numba(retrieval: str, samples: int, backend) -> bool:
    if backend is None:
        return samples >= NUMBA_MIN_READINGS[retrieval] and numba_module() is not None
    use = check_choice("backend", backend, BACKENDS) == "numba"
    if use and numba_module() is None:
        raise InputError(
            f"backend 'numba' needs numba (pip install 'wavemeter[fast]') and "
            f"{NO_NUMBA_VARIABLE} unset",
            parameter="backend",
        )
    return use


def _readings_and_offset(powers, ports: int, offset_w) -> tuple[np.ndarray, np.ndarray]:
    readings = reading_array(powers, ports=ports)
    offset = np.zeros(ports) if offset_w is None else np.asarray(offset_w, dtype=float)
    if offset.shape != (ports,):
        raise InputError(
            f"offset_w must hold {ports} values (W), one per port, got shape {offset.shape}",
            parameter="offset_w",
        )
    return readings, offset


def _checked(out_valid: tuple[np.ndarray, bool], readings: np.ndarray, check: bool) -> np.ndarray:
    out, valid = out_valid
    if check and not valid:
        # its messages name the rows (a total at rounding level of zero may pass it)
        check_powers(readings, ports=readings.shape[1])
    return out


def _pinv(powers, map_pinv, offset_w, origin, scale, check, backend) -> np.ndarray:
    inverse = np.asarray(map_pinv, dtype=float)
    if inverse.ndim != 2 or inverse.shape[0] != 3:
        raise InputError(
            f"map_pinv must have shape (3, n), got {inverse.shape}", parameter="map_pinv"
        )
    readings, offset = _readings_and_offset(powers, inverse.shape[1], offset_w)
    origin, scale = float(origin), float(scale)
    if _use_numba("pinv", readings.shape[0], backend):
        matrices = (inverse, np.zeros((3, 3)), np.zeros(3))  # no cone frame
        found = _numba_path(False, readings, matrices, offset, origin, scale)
    else:
        found = _numpy_pinv(readings, inverse, offset, origin, scale, check)
    return _checked(found, readings, check)


def _ml(powers, map_, noise_std_w, offset_w, origin, scale, check, backend) -> np.ndarray:
    matrix = np.asarray(map_, dtype=float)
    if matrix.ndim != 2 or matrix.shape[1] != 3:
        raise InputError(f"map_ must have shape (n, 3), got {matrix.shape}", parameter="map_")
    readings, offset = _readings_and_offset(powers, matrix.shape[0], offset_w)
    origin, scale = float(origin), float(scale)
    if _use_numba("ml", readings.shape[0], backend):
        kappa, to_frame, to_objects = cone_frame(matrix, noise_weighted_map(matrix, noise_std_w))
        matrices = (to_frame.T, np.ascontiguousarray(to_objects), kappa)
        found = _numba_path(True, readings, matrices, offset, origin, scale)
    else:
        found = _numpy_ml(readings, matrix, noise_std_w, offset, origin, scale, check)
    return _checked(found, readings, check)


def fused_pinv_frequency_hz(
    powers,
    map_pinv,
    center_hz: float,
    fsr_hz: float,
    *,
    offset_w=None,
    check: bool = True,
    backend: str | None = None,
) -> np.ndarray:
    """Frequency (Hz) ``f0 + t FSR / (2 pi)`` of readings, pseudo-inverse phase ``t``.

    ``t = atan2(x_2, x_1)`` of ``x = A+ (p - o)``, as
    :func:`~wavemeter.calibration.methods.learned.retrieve_phase_rad` gives it.

    Parameters
    ----------
    powers : array_like, shape (N, n) or (n,)
        Port readings (W), offsets not yet removed.
    map_pinv : array_like, shape (3, n)
        Moore-Penrose inverse ``A+`` of the map (1/W); its first two rows are used.
    center_hz, fsr_hz : float
        Phase origin ``f0`` and FSR (Hz).
    offset_w : None or array_like, shape (n,)
        What every reading carries besides the light (W, per port), subtracted first.
    check : bool
        Refuse NaN, inf and dark readings (raw total power not in (0, inf)) with the
        :class:`~wavemeter.exceptions.InputError` of
        :func:`~wavemeter.validation.check_powers`.
    backend : None, "numba" or "numpy"
        None: numba from ``NUMBA_MIN_READINGS["pinv"]`` readings on, when it is there;
        else numpy.

    Returns
    -------
    ndarray, shape (N,), Hz, within ``f0 +- FSR/2``
    """
    return _pinv(powers, map_pinv, offset_w, center_hz, fsr_hz / (2.0 * np.pi), check, backend)


def fused_pinv_phase_rad(
    powers, map_pinv, *, offset_w=None, check: bool = False, backend: str | None = None
) -> np.ndarray:
    """Pseudo-inverse phase ``atan2(x_2, x_1)`` (rad, in [-pi, pi]) of ``x = A+ (p - o)``.

    Parameters as :func:`fused_pinv_frequency_hz`; unchecked by default (readings the
    caller has validated).

    Returns
    -------
    ndarray, shape (N,), rad
    """
    return _pinv(powers, map_pinv, offset_w, 0.0, 1.0, check, backend)


def fused_ml_frequency_hz(
    powers,
    map_,
    center_hz: float,
    fsr_hz: float,
    *,
    noise_std_w=None,
    offset_w=None,
    check: bool = True,
    backend: str | None = None,
) -> np.ndarray:
    """Frequency (Hz) ``f0 + t FSR / (2 pi)`` of readings, maximum-likelihood phase ``t``.

    ``t`` as :func:`~wavemeter.model.retrieval.cone_ml_phase_rad` gives it for ``p - o``.

    Parameters
    ----------
    powers : array_like, shape (N, n) or (n,)
        Port readings (W), offsets not yet removed.
    map_ : array_like, shape (n, 3)
        The map ``A`` (W), of rank 3.
    center_hz, fsr_hz : float
        Phase origin ``f0`` and FSR (Hz).
    noise_std_w : None, float or array_like, shape (n,)
        Detector noise per port (W); None or one number weighs every port equally.
    offset_w, check :
        As for :func:`fused_pinv_frequency_hz`.
    backend : None, "numba" or "numpy"
        None: numba from ``NUMBA_MIN_READINGS["ml"]`` readings on, when it is there; else
        numpy.

    Returns
    -------
    ndarray, shape (N,), Hz, in ``[f0 - FSR/2, f0 + FSR/2)``
    """
    return _ml(
        powers, map_, noise_std_w, offset_w, center_hz, fsr_hz / (2.0 * np.pi), check, backend
    )


def fused_ml_phase_rad(
    powers, map_, *, noise_std_w=None, offset_w=None, check: bool = False, backend=None
) -> np.ndarray:
    """Maximum-likelihood phase (rad, in [-pi, pi)) of readings less their offsets.

    Parameters as :func:`fused_ml_frequency_hz`; unchecked by default (readings the
    caller has validated).

    Returns
    -------
    ndarray, shape (N,), rad
    """
    return _ml(powers, map_, noise_std_w, offset_w, 0.0, 1.0, check, backend)

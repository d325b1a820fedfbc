"""Fused phase retrieval: check, offsets, map product, phase and scale in one pass.

A reading ``p`` (n ports, offsets ``o``) is retrieved by the paper's pseudo-inverse,
``x = A+ (p - o)`` and ``t = atan2(x_2, x_1)``, or by the cone-constrained maximum
likelihood of :func:`~wavemeter.model.retrieval.cone_ml_phase_rad`; its frequency is
``f = f0 + t FSR / (2 pi)``. Written with numpy this walks the readings many times (the
finite check, the offsets, the products, the arctangent, the scale; the maximum likelihood
a few times per Newton step) and leaves a temporary at each step. Here:

* **numba** (the optional extra ``fast``): one pass per reading, on every core, over
  blocks of ``BLOCK_ROWS`` readings, with the check that refuses NaN, inf and dark readings
  folded in (:func:`_build_kernel`). A kernel is compiled per port count (a constant
  stride lets the compiler vectorise the map product). Each block forms its products and
  total powers in the cache; the maximum likelihood then takes its Newton steps for the
  whole block at once (a vectorised loop per step); last the arctangent, in a vectorised
  loop too: it is written out (Cephes' rational ``atan`` on ``[0, tan(pi/8)]`` after a
  range reduction exact to rounding, quadrant by sign), since the C library's ``atan2``
  cannot be vectorised and costs 7 times numpy's own vectorised ``arctan2``. It is within
  1.6 units in the last place of the exact value (numpy's within 1). ``fastmath`` stays
  off: no reassociation, so results do not depend on the vector width.
* **numpy** (the fallback; and small batches, below ``NUMBA_MIN_READINGS``, where numba's
  import and, on a busy machine, the wait for its threads cost more than they save): for
  the pseudo-inverse one matrix product per ``NUMPY_CHUNK_ROWS`` readings gives both
  quadratures and the total power as contiguous rows in the cache, then ``arctan2``,
  scale and shift in place; the maximum likelihood is
  :func:`~wavemeter.validation.check_powers` and
  :func:`~wavemeter.model.retrieval.cone_ml_phase_rad` as they are.

Both paths give the steps one by one to rounding (1e-12 rad covers it: the products'
rounding relative to the quadratures' length, times the map's condition number; for the
maximum likelihood also its root tolerance ``TOLERANCE``). Readings are refused by
:func:`~wavemeter.validation.check_powers` itself, with its messages, whenever the fused
check finds a NaN, inf or dark reading.

numba is imported on the first batch large enough to use it, never when wavemeter is
imported; the environment variable ``WAVEMETER_NO_NUMBA`` set to anything but ``""`` or
``"0"`` keeps the numpy path. :func:`kernel_backend` tells which path large batches take.
The compiled kernels are cached on disk (numba's ``cache=True``): the first run compiles
each (1.6 s the pseudo-inverse's, 3.2 s the maximum likelihood's, per port count), later
processes load them (0.2 s, after numba's import, 0.1 s).
"""

from __future__ import annotations

import functools
import os

import numpy as np

from ..exceptions import InputError
from ..validation import check_choice, check_powers, reading_array
from .retrieval import MAX_STEPS, TOLERANCE, cone_frame, cone_ml_phase_rad, noise_weighted_map

__all__ = [
    "BACKENDS",
    "BLOCK_ROWS",
    "NO_NUMBA_VARIABLE",
    "NUMBA_MIN_READINGS",
    "NUMPY_CHUNK_ROWS",
    "fused_ml_frequency_hz",
    "fused_ml_phase_rad",
    "fused_pinv_frequency_hz",
    "fused_pinv_phase_rad",
    "kernel_backend",
]

#: environment variable that, set to anything but "" or "0", keeps the numpy path
NO_NUMBA_VARIABLE = "WAVEMETER_NO_NUMBA"
#: fewest readings the numba kernels take, by retrieval. With both cores free the warm
#: kernels win from 100 readings on (pinv 5 us vs numpy 14 us, ml 40 vs 210 us), but a
#: batch that takes numba first imports it and loads the kernel (0.3 s; 1.5-3 s to compile
#: on a first run), and with another process on a core each call waits for its thread to
#: be scheduled (4-8 ms measured). Below these sizes numpy takes under ~0.1 ms (pinv) and
#: ~0.4 ms (ml): no gain worth either cost
NUMBA_MIN_READINGS = {"pinv": 10_000, "ml": 1_000}
#: readings per block of the numba kernel: its quadratures (3 x 32 kB) stay in the cache
BLOCK_ROWS = 4096
#: readings from which the numba kernel runs on every core (fewer: on this thread). Waking
#: the other threads costs tens of microseconds on an idle machine (measured crossover: pinv
#: about 5e4 readings, ml a few thousand); when another process holds a core, each parallel
#: call waits for its thread to be scheduled (4-8 ms measured): set NUMBA_NUM_THREADS=1 then
PARALLEL_MIN_READINGS = {"pinv": 1 << 16, "ml": 1 << 12}
#: readings per product of the numpy path: its rows (3 x 512 kB) stay in the cache
NUMPY_CHUNK_ROWS = 1 << 16
#: ``backend`` values: None picks numba for large batches when it is there
BACKENDS = ("numba", "numpy")

# Cephes atan (S. L. Moshier): atan(a) = a + a z P(z) / Q(z), z = a^2, |a| <= tan(pi/8)
_P0 = -8.750608600031904122785e-1
_P1 = -1.615753718733365076637e1
_P2 = -7.500855792314704667340e1
_P3 = -1.228866684490136173410e2
_P4 = -6.485021904942025371773e1
_Q0 = 2.485846490142306297962e1
_Q1 = 1.650270098316988542046e2
_Q2 = 4.328810604912902668951e2
_Q3 = 4.853903996359136964868e2
_Q4 = 1.945506571482613964425e2
#: pi/4 - fl(pi/4): the constants' rounding, added back after each reflection
_PI_4_LOW = 3.061616997868382943065e-17
_PI_4 = 0.25 * np.pi
_PI_2 = 0.5 * np.pi
_PI = np.pi
#: above this ratio of the smaller quadrature to the larger, reduce by pi/4 (Cephes' 0.66)
_REDUCE_RATIO = 0.66


#: ``"child"`` turns True in a process forked after this one ran a kernel: numba's threading
#: layer here (GNU OpenMP) kills such a child at its first parallel loop, so it runs numpy
_FORK_GUARD = {"armed": False, "child": False}


def _arm_fork_guard() -> None:
    if not _FORK_GUARD["armed"]:
        _FORK_GUARD["armed"] = True
        if hasattr(os, "register_at_fork"):  # where processes can fork
            os.register_at_fork(after_in_child=functools.partial(_FORK_GUARD.update, child=True))


@functools.cache
def _numba_module():
    """The numba module, or None when it is missing or ``WAVEMETER_NO_NUMBA`` is set."""
    if os.environ.get(NO_NUMBA_VARIABLE, "") not in ("", "0"):
        return None
    try:
        import numba
    except ImportError:
        return None
    return numba


def _numba_usable() -> bool:
    return _numba_module() is not None and not _FORK_GUARD["child"]


def kernel_backend() -> str:
    """The path batches of ``NUMBA_MIN_READINGS`` readings or more take: ``"numba"`` or
    ``"numpy"`` (numba missing, ``WAVEMETER_NO_NUMBA`` set, or a process forked after its
    parent ran a kernel). Imports numba to tell."""
    return "numba" if _numba_usable() else "numpy"


@functools.cache
def _build_kernel(ports: int, ml: bool, parallel: bool):
    """The numba kernel for readings of ``ports`` ports, pseudo-inverse or (``ml``)
    maximum-likelihood retrieval, on every core (``parallel``) or on this thread;
    compiled on its first call, then loaded from the cache.

    ``kernel(readings, offset_w, frame_map, to_objects, kappa, origin, scale, out)`` writes
    ``origin + scale * t`` of each reading ``p`` (a row of the C-contiguous ``readings``,
    shape (N, ports)) to ``out`` (N,) and returns how many readings are NaN, inf or dark
    (raw total power not in (0, inf)). The phase ``t`` comes from ``y = (p - o) @
    frame_map``: for the pseudo-inverse ``frame_map = A+[:2].T`` and ``t = atan2(y_2,
    y_1)`` (``to_objects`` and ``kappa`` unused); for the maximum likelihood ``frame_map``,
    ``to_objects`` and ``kappa`` are the cone frame of
    :func:`~wavemeter.model.retrieval.cone_ml_phase_rad`, whose secular root is found by
    the same bracketed Newton steps, each step for the whole block at once (vectorised;
    a reading stops moving once converged), and ``t`` is wrapped to [-pi, pi). The
    arctangent takes quadratures below 8e307 in magnitude (their sum must not overflow).
    """
    numba = _numba_module()
    block_rows = BLOCK_ROWS
    # a free variable of the kernel, so that numba's cache (keyed by the kernel's code and
    # the values of its free variables, not by the decorator's options) keeps both kinds
    blocks_of = numba.prange if parallel else range

    @numba.njit(parallel=parallel, fastmath=False, error_model="numpy", cache=True)
    def kernel(readings, offset_w, frame_map, to_objects, kappa, origin, scale, out):
        rows = readings.shape[0]
        flat = readings.reshape(rows * ports)  # constant stride: a vectorised product
        refused = 0
        for block in blocks_of((rows + block_rows - 1) // block_rows):
            start = block * block_rows
            size = min(block_rows, rows - start)
            real = np.empty(size)
            imag = np.empty(size)
            third = np.empty(size)
            total = np.empty(size)
            for k in range(size):
                y0 = 0.0
                y1 = 0.0
                y2 = 0.0
                power = 0.0
                first = (start + k) * ports
                for j in range(ports):
                    raw = flat[first + j]
                    power += raw
                    light = raw - offset_w[j]
                    y0 += light * frame_map[j, 0]
                    y1 += light * frame_map[j, 1]
                    if ml:
                        y2 += light * frame_map[j, 2]
                real[k] = y0
                imag[k] = y1
                third[k] = y2
                total[k] = power
            if ml:
                # the secular root of every reading by bracketed Newton steps, one step
                # for the whole block at a time (vectorised); converged readings stay
                k0 = kappa[0]
                k1 = kappa[1]
                k2 = kappa[2]
                root = np.zeros(size)
                lower = np.full(size, -1.0 / k2)
                upper = np.full(size, -1.0 / k0)
                last = upper - lower
                going = np.ones(size, dtype=np.int64)
                for _ in range(MAX_STEPS):
                    moving = 0
                    for k in range(size):
                        x = root[k]
                        r0 = 1.0 / (1.0 + k0 * x)
                        r1 = 1.0 / (1.0 + k1 * x)
                        r2 = 1.0 / (1.0 + k2 * x)
                        t0 = k0 * (real[k] * real[k]) * (r0 * r0)
                        t1 = k1 * (imag[k] * imag[k]) * (r1 * r1)
                        t2 = k2 * (third[k] * third[k]) * (r2 * r2)
                        value = t0 + t1 + t2
                        slope = -2.0 * (t0 * k0 * r0 + t1 * k1 * r1 + t2 * k2 * r2)
                        a = x if value >= 0.0 else lower[k]
                        b = x if value <= 0.0 else upper[k]
                        newton = x - value / slope
                        inside = newton >= a and newton <= b and abs(newton - x) <= 0.5 * last[k]
                        step = (newton if inside else 0.5 * (a + b)) - x
                        moved = abs(step) * max(abs(k0 * r0), abs(k1 * r1), abs(k2 * r2))
                        on = going[k] > 0
                        root[k] = x + step if on else x
                        lower[k] = a if on else lower[k]
                        upper[k] = b if on else upper[k]
                        last[k] = abs(step) if on else last[k]
                        going[k] = 1 if (on and moved > TOLERANCE) else 0
                        moving += going[k]
                    if moving == 0:
                        break
                for k in range(size):
                    x = root[k]
                    z0 = real[k] / (1.0 + x * k0)
                    z1 = imag[k] / (1.0 + x * k1)
                    z2 = third[k] / (1.0 + x * k2)
                    o0 = z0 * to_objects[0, 0] + z1 * to_objects[1, 0] + z2 * to_objects[2, 0]
                    o1 = z0 * to_objects[0, 1] + z1 * to_objects[1, 1] + z2 * to_objects[2, 1]
                    o2 = z0 * to_objects[0, 2] + z1 * to_objects[1, 2] + z2 * to_objects[2, 2]
                    # a source power below zero: the other nappe, phase of -x
                    sign = -1.0 if o2 < 0.0 else 1.0
                    real[k] = sign * o0
                    imag[k] = sign * o1
            dest = out[start : start + size]
            bad = 0
            for k in range(size):
                x = real[k]
                y = imag[k]
                ax = abs(x)
                ay = abs(y)
                small = min(ax, ay)
                large = max(ax, ay)
                # atan(small / large), in [0, pi/4]; above the ratio 0.66 through
                # atan(a) = pi/4 + atan((a - 1) / (a + 1))
                reduce = small > _REDUCE_RATIO * large
                top = small - large if reduce else small
                bottom = small + large if reduce else large
                a = top / bottom if bottom > 0.0 else 0.0
                z = a * a
                p = (((_P0 * z + _P1) * z + _P2) * z + _P3) * z + _P4
                q = ((((z + _Q0) * z + _Q1) * z + _Q2) * z + _Q3) * z + _Q4
                t = a * (z * p / q) + a
                t = (t + _PI_4_LOW) + _PI_4 if reduce else t
                t = (_PI_2 - t) + 2.0 * _PI_4_LOW if ay > ax else t
                t = (_PI - t) + 4.0 * _PI_4_LOW if np.copysign(1.0, x) < 0.0 else t
                t = np.copysign(t, y)
                if ml:
                    t = -_PI if t >= _PI else t
                dest[k] = origin + scale * t
                power = total[k]
                bad += 0 if (power > 0.0 and power < np.inf) else 1
            refused += bad
        return refused

    return kernel


def _numba_path(ml, readings, matrices, offset_w, origin, scale) -> tuple[np.ndarray, bool]:
    out = np.empty(readings.shape[0])
    parallel = readings.shape[0] >= PARALLEL_MIN_READINGS["ml" if ml else "pinv"]
    kernel = _build_kernel(readings.shape[1], ml, parallel)
    _arm_fork_guard()
    refused = kernel(np.ascontiguousarray(readings), offset_w, *matrices, origin, scale, out)
    return out, refused == 0 and out.size > 0


def _numpy_pinv(readings, frame_map, offset_w, origin, scale, check) -> tuple[np.ndarray, bool]:
    weights = frame_map.T
    # one product per chunk: both quadratures (and, to check, the total power) as
    # contiguous rows that stay in the cache
    stacked = np.vstack([weights, np.ones(readings.shape[1])]) if check else weights
    shift = (weights @ offset_w)[:, None] if offset_w.any() else None
    samples = readings.shape[0]
    out = np.empty(samples)
    rows = np.empty((stacked.shape[0], min(samples, NUMPY_CHUNK_ROWS)))
    valid = samples > 0
    for start in range(0, samples, NUMPY_CHUNK_ROWS):
        stop = min(start + NUMPY_CHUNK_ROWS, samples)
        chunk = rows[:, : stop - start]
        with np.errstate(invalid="ignore"):  # inf readings: refused below, or flagged
            np.matmul(stacked, readings[start:stop].T, out=chunk)
        if shift is not None:
            chunk[:2] -= shift
        phase = out[start:stop]
        np.arctan2(chunk[1], chunk[0], out=phase)
        if scale != 1.0:
            phase *= scale
        if origin != 0.0:
            phase += origin
        if check:
            total = chunk[2]
            valid = valid and total.min() > 0.0 and total.max() < np.inf
    return out, bool(valid)


def _numpy_ml(readings, map_, noise_std_w, offset_w, origin, scale, check):
    if check:
        check_powers(readings, ports=readings.shape[1])
    light = readings - offset_w if offset_w.any() else readings
    return origin + cone_ml_phase_rad(light, map_, noise_std_w=noise_std_w) * scale, True


def _use_numba(retrieval: str, samples: int, backend) -> bool:
    if backend is None:
        return samples >= NUMBA_MIN_READINGS[retrieval] and _numba_usable()
    use = check_choice("backend", backend, BACKENDS) == "numba"
    if use and not _numba_usable():
        raise InputError(
            f"backend 'numba' needs numba (pip install 'wavemeter[fast]'), {NO_NUMBA_VARIABLE} "
            "unset, and a process not forked after its parent ran a kernel (start processes "
            "with 'spawn')",
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
    frame_map = np.ascontiguousarray(inverse[:2].T)
    origin, scale = float(origin), float(scale)
    if _use_numba("pinv", readings.shape[0], backend):
        matrices = (frame_map, np.zeros((3, 3)), np.zeros(3))  # no cone frame
        found = _numba_path(False, readings, matrices, offset, origin, scale)
    else:
        found = _numpy_pinv(readings, frame_map, offset, origin, scale, check)
    return _checked(found, readings, check)


def _ml(powers, map_, noise_std_w, offset_w, origin, scale, check, backend) -> np.ndarray:
    matrix = np.asarray(map_, dtype=float)
    if matrix.ndim != 2 or matrix.shape[1] != 3:
        raise InputError(f"map_ must have shape (n, 3), got {matrix.shape}", parameter="map_")
    readings, offset = _readings_and_offset(powers, matrix.shape[0], offset_w)
    origin, scale = float(origin), float(scale)
    if _use_numba("ml", readings.shape[0], backend):
        kappa, to_frame, to_objects = cone_frame(matrix, noise_weighted_map(matrix, noise_std_w))
        matrices = (np.ascontiguousarray(to_frame), np.ascontiguousarray(to_objects), kappa)
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
    :func:`~wavemeter.calibration.learned.retrieve_phase_rad` gives it.

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

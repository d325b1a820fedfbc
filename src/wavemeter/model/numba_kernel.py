"""The numba kernel of the fused phase retrieval (:mod:`wavemeter.model.kernels`).

One pass per reading with the check that refuses NaN, inf and dark readings folded in
(:func:`build_kernel`), compiled per port count: unsigned row numbers and a constant stride
let the compiler load the readings as whole vectors, and the map's coefficients are
constants of the loop. The pseudo-inverse takes each reading's product, arctangent, scale
and check in one vectorised loop; the maximum likelihood forms a block's products first,
takes its Newton steps for the whole block at once (a vectorised loop per step), then its
arctangents. The arctangent is written out (Cephes' rational ``atan`` on ``[-0.66, 0.66]``
after a range reduction exact to rounding, octant by sign), since the C library's ``atan2``
cannot be vectorised and costs 7 times numpy's own vectorised ``arctan2``: within 1.5 units
in the last place of the exact value over 1e7 inputs, subnormal to 8e307, the axes and
diagonals included (numpy's within 1). Of ``fastmath`` only the contraction into fused
multiply-adds.

numba (the optional extra ``fast``) is imported on the first batch large enough to use it,
never when wavemeter is imported; the environment variable ``WAVEMETER_NO_NUMBA`` set to
anything but ``""`` or ``"0"`` keeps the numpy path. :func:`kernel_backend` tells which
path large batches take. The compiled kernels are cached on disk (numba's ``cache=True``):
the first run compiles each (0.8 s the pseudo-inverse's, 1.6 s the maximum likelihood's,
per port count), later processes load them (0.2 s, after numba's import, 0.15 s).
"""

from __future__ import annotations

import functools
import os

import numpy as np

from .retrieval import MAX_STEPS, TOLERANCE

__all__ = ["BLOCK_ROWS", "NO_NUMBA_VARIABLE", "build_kernel", "kernel_backend", "numba_module"]

#: environment variable that, set to anything but "" or "0", keeps the numpy path
NO_NUMBA_VARIABLE = "WAVEMETER_NO_NUMBA"
#: readings per block of the numba kernel: a block's maximum-likelihood coordinates and
#: Newton state stay in the cache; a shared call is cut into whole blocks
BLOCK_ROWS = 4096

# Cephes atan (S. L. Moshier): atan(a) = a + a z P(z) / Q(z), z = a^2, |a| <= 0.66
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
#: reduce by pi/4 where the smaller quadrature times this exceeds the larger (a ratio above
#: Cephes' 0.66); as a product of the smaller, it still holds for the tiniest subnormals, where
#: 0.66 times the larger would round up to the smaller itself
_REDUCE_FACTOR = 1.0 / 0.66
#: the largest finite double: a total power above it is inf
_LARGEST = float(np.finfo(float).max)


@functools.cache
def numba_module():
    """The numba module, or None when it is missing or ``WAVEMETER_NO_NUMBA`` is set."""
    if os.environ.get(NO_NUMBA_VARIABLE, "") not in ("", "0"):
        return None
    try:
        import numba
    except ImportError:
        return None
    return numba


def kernel_backend() -> str:
    """The path batches of :data:`~wavemeter.model.kernels.NUMBA_MIN_READINGS` readings or
    more take: ``"numba"`` or ``"numpy"`` (numba missing or ``WAVEMETER_NO_NUMBA`` set).
    Imports numba to tell."""
    return "numpy" if numba_module() is None else "numba"


@functools.cache
def build_kernel(ports: int, ml: bool):
    """The numba kernel for readings of ``ports`` ports, pseudo-inverse or (``ml``)
    maximum-likelihood retrieval; compiled on its first call, then loaded from the cache.

    ``kernel(readings, offset, weights, to_objects, kappa, origin, scale, out, start,
    stop)`` writes ``origin + scale * t`` of each reading ``p`` of rows ``start`` to
    ``stop`` of the C-contiguous ``readings`` (N, ports) to the same rows of ``out`` (N,)
    and returns how many of them are NaN, inf or dark (raw total power not in (0, inf));
    it lets other threads run meanwhile (``nogil``). ``offset`` (``o``) and the three rows
    of ``weights`` are tuples of ``ports`` numbers (constants of the loops, where arrays
    would be loaded again for every reading). The phase ``t`` comes from ``y = W (p - o)``:
    for the pseudo-inverse ``W = A+`` and ``t = atan2(y_2, y_1)`` (its third row,
    ``to_objects`` and ``kappa`` unused); for the maximum likelihood ``W``, ``to_objects``
    and ``kappa`` are the cone frame of
    :func:`~wavemeter.model.retrieval.cone_ml_phase_rad` (``W`` its ``to_frame``
    transposed), whose secular root is found by the same bracketed Newton steps, each step
    for a whole block at once (vectorised; a reading stops moving once converged), and
    ``t`` is wrapped to [-pi, pi). The arctangent takes quadratures below 8e307 in
    magnitude (their sum must not overflow).
    """
    numba = numba_module()
    # numba's cache keys a kernel by its code and the values of its free variables, not by
    # the decorator's options nor by constants it reads from other modules: every setting
    # the kernel depends on is one of these variables
    block_rows = BLOCK_ROWS
    max_steps = MAX_STEPS
    tolerance = TOLERANCE
    # unsigned row numbers: numba then leaves out its wrap-around of negative indices, and
    # the compiler sees reading k at k * ports, so it loads readings as whole vectors
    unsigned = numba.uint64
    stride = unsigned(ports)

    # of fastmath only the contraction of a product and a sum into one multiply-add
    # (rounded once, not twice): NaN and inf stay what they are (the check relies on them),
    # nothing is reassociated
    @numba.njit(nogil=True, fastmath={"contract"}, error_model="numpy", cache=True)
    def kernel(readings, offset, weights, to_objects, kappa, origin, scale, out, start, stop):
        flat = readings.reshape(readings.shape[0] * ports)
        first_row, second_row, third_row = weights

        def product(k):
            """Quadratures (and, for ml, the third coordinate) and raw total power of
            reading ``k``."""
            y0 = 0.0
            y1 = 0.0
            y2 = 0.0
            power = 0.0
            base = k * stride
            for j in range(ports):
                raw = flat[base + unsigned(j)]
                power += raw
                light = raw - offset[j]
                y0 += light * first_row[j]
                y1 += light * second_row[j]
                if ml:
                    y2 += light * third_row[j]
            return y0, y1, y2, power

        def dark(power):
            """1 for a raw total power not in (0, inf) (NaN included), else 0; written
            with the largest double, which compiles to fewer instructions than inf."""
            return 0 if (power > 0.0 and power <= _LARGEST) else 1

        def arctangent(y, x):
            """atan2(y, x): atan(small / large) in [0, pi/4], above the ratio 0.66 through
            atan(a) = pi/4 + atan((a - 1) / (a + 1)), then reflected to its octant."""
            ax = abs(x)
            ay = abs(y)
            small = min(ax, ay)
            large = max(ax, ay)
            reduce = _REDUCE_FACTOR * small > large
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
            return np.copysign(t, y)

        refused = 0
        for begin in range(start, stop, block_rows):
            first = unsigned(begin)
            last = unsigned(min(stop, begin + block_rows))
            bad = 0
            if ml:
                # every reading's product first, then the secular roots by bracketed Newton
                # steps, one step for the whole block at a time (vectorised); converged
                # readings stay
                size = last - first
                real = np.empty(size)
                imag = np.empty(size)
                third = np.empty(size)
                for i in range(size):
                    real[i], imag[i], third[i], power = product(first + i)
                    bad += dark(power)
                k0 = kappa[0]
                k1 = kappa[1]
                k2 = kappa[2]
                root = np.zeros(size)
                lower = np.full(size, -1.0 / k2)
                upper = np.full(size, -1.0 / k0)
                span = upper - lower
                going = np.ones(size, dtype=np.int64)
                for _ in range(max_steps):
                    moving = 0
                    for i in range(size):
                        x = root[i]
                        r0 = 1.0 / (1.0 + k0 * x)
                        r1 = 1.0 / (1.0 + k1 * x)
                        r2 = 1.0 / (1.0 + k2 * x)
                        t0 = k0 * (real[i] * real[i]) * (r0 * r0)
                        t1 = k1 * (imag[i] * imag[i]) * (r1 * r1)
                        t2 = k2 * (third[i] * third[i]) * (r2 * r2)
                        value = t0 + t1 + t2
                        slope = -2.0 * (t0 * k0 * r0 + t1 * k1 * r1 + t2 * k2 * r2)
                        a = x if value >= 0.0 else lower[i]
                        b = x if value <= 0.0 else upper[i]
                        newton = x - value / slope
                        inside = newton >= a and newton <= b and abs(newton - x) <= 0.5 * span[i]
                        step = (newton if inside else 0.5 * (a + b)) - x
                        moved = abs(step) * max(abs(k0 * r0), abs(k1 * r1), abs(k2 * r2))
                        on = going[i] > 0
                        root[i] = x + step if on else x
                        lower[i] = a if on else lower[i]
                        upper[i] = b if on else upper[i]
                        span[i] = abs(step) if on else span[i]
                        going[i] = 1 if (on and moved > tolerance) else 0
                        moving += going[i]
                    if moving == 0:
                        break
                for i in range(size):
                    x = root[i]
                    z0 = real[i] / (1.0 + x * k0)
                    z1 = imag[i] / (1.0 + x * k1)
                    z2 = third[i] / (1.0 + x * k2)
                    o0 = z0 * to_objects[0, 0] + z1 * to_objects[1, 0] + z2 * to_objects[2, 0]
                    o1 = z0 * to_objects[0, 1] + z1 * to_objects[1, 1] + z2 * to_objects[2, 1]
                    o2 = z0 * to_objects[0, 2] + z1 * to_objects[1, 2] + z2 * to_objects[2, 2]
                    # a source power below zero: the other nappe, phase of -x
                    sign = -1.0 if o2 < 0.0 else 1.0
                    t = arctangent(sign * o1, sign * o0)
                    out[first + i] = origin + scale * (-_PI if t >= _PI else t)
            else:
                # one pass: product, arctangent, scale and check of each reading in turn
                for k in range(first, last):
                    x, y, _, power = product(k)
                    out[k] = origin + scale * arctangent(y, x)
                    bad += dark(power)
            refused += bad
        return refused

    return kernel

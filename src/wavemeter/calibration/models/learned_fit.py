"""The learned method's fit as pure functions: the delay search, the map, the noise.

:func:`fit_learned_map` searches the delay ``tau`` minimising ``J(tau)`` on the binned
moments of the sweep (:mod:`~wavemeter.calibration.models.moments`) and fits the map there
(paper Eq. 20-23); :func:`fit_learned_map_chunks` does the same for a sweep read in chunks.
:func:`retrieve_phase_rad` and :func:`predict_frequency_hz` are the paper's retrieval
(Eq. 24-25). :class:`~wavemeter.calibration.methods.learned.Calibrator` computes the same
numbers (a test holds them to 1e-12). Theory: the user guide's theory pages.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy import linalg

from ...exceptions import InputError
from ...model.cone import phase_to_frequency_hz
from ...validation import MIN_SAMPLES
from .delay_search import DelaySearchResult
from .linear_map import map_cost, object_vectors
from .moment_search import search_moment_delay
from .moments import FringeMoments, largest_search_delay_s

__all__ = [
    "AFFINE_MIN_POWER_SPREAD",
    "LearnedFit",
    "MAX_MOMENT_BYTES",
    "PER_PORT_MIN_DOF",
    "RETRIEVALS",
    "fit_learned_map",
    "fit_learned_map_chunks",
    "gram_objects",
    "moment_fit",
    "port_noise_from_squares",
    "port_noise_std_w",
    "predict_frequency_hz",
    "relative_map",
    "retrieve_phase_rad",
]

RETRIEVALS = ("pinv", "ml")
#: relative spread of the monitored power above which per-port offsets are fitted
AFFINE_MIN_POWER_SPREAD = 0.02
#: residual degrees of freedom a port needs for a noise estimate of its own
PER_PORT_MIN_DOF = 30
#: most memory the binned moments of a large sweep may take (bytes): they grow with the span
#: in fringes (~80 bins per FSR, ~0.5 kB per bin for 3 ports), whatever the readings
MAX_MOMENT_BYTES = 64 << 20


def port_noise_std_w(
    residual: np.ndarray, columns: int, shared: int = 1
) -> tuple[np.ndarray, float]:
    """Per-port noise (W) from a fit residual, and its degrees of freedom.

    Each port's residual has ``N - k - q/n`` degrees of freedom (``k`` map columns per
    port, ``q`` nonlinear parameters shared by the ``n`` ports: the delay, or the thermal
    model's three). With at least ``PER_PORT_MIN_DOF`` of them each port gets its own
    estimate; otherwise every port gets the pooled one, on ``N n - n k - q`` degrees of
    freedom.

    Parameters
    ----------
    residual : ndarray, shape (N, n)
        Readings minus the fitted model (W).
    columns : int
        Map columns per port ``k`` (3, or 4 with offsets).
    shared : int
        Nonlinear parameters ``q`` shared by the ports (1: the delay).

    Returns
    -------
    noise_std_w : ndarray, shape (n,)
    dof : float
    """
    squares = np.einsum("ij,ij->j", residual, residual)
    return port_noise_from_squares(squares, residual.shape[0], columns, shared)


def port_noise_from_squares(squares: np.ndarray, samples: int, columns: int, shared: int):
    """:func:`port_noise_std_w` from each port's summed squared residual (n,), W^2."""
    ports = squares.size
    per_port_dof = samples - columns - shared / ports
    if per_port_dof >= PER_PORT_MIN_DOF:
        return np.sqrt(squares / per_port_dof), per_port_dof
    pooled_dof = max(samples * ports - ports * columns - float(shared), 1.0)
    return np.full(ports, np.sqrt(squares.sum() / pooled_dof)), pooled_dof


def retrieve_phase_rad(powers, map_pinv: np.ndarray) -> np.ndarray:
    """Phase ``atan2(x_hat_2, x_hat_1)`` (rad) of ``x_hat = A+ p`` for readings (N, n).

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> phase = wm.retrieve_phase_rad(powers[:3], np.linalg.pinv(cal.map_))
    >>> print(np.allclose(phase, cal.phase(powers[:3])))
    True
    """
    readings = np.asarray(powers, dtype=float)
    # two matrix-vector products keep both quadratures contiguous for the arctangent
    return np.arctan2(readings @ map_pinv[1], readings @ map_pinv[0])


def predict_frequency_hz(powers, map_: np.ndarray, center_hz: float, fsr_hz: float) -> np.ndarray:
    """Frequency (Hz) of readings (N, n) under a map (n, 3): pinv, arctangent, FSR scale.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> f_direct = wm.predict_frequency_hz(powers[:3], cal.map_, cal.center_hz_, cal.fsr_hz_)
    >>> print(np.allclose(f_direct, cal.predict(powers[:3]), rtol=0, atol=1.0))  # within 1 Hz
    True
    """
    return phase_to_frequency_hz(retrieve_phase_rad(powers, linalg.pinv(map_)), center_hz, fsr_hz)


@dataclass(frozen=True)
class LearnedFit:
    """Outcome of :func:`fit_learned_map`.

    Attributes
    ----------
    delay_s : float
        Delay ``tau`` at the minimum of ``J`` (s).
    delay_std_s : float or None
        Its standard error (s): ``sqrt(s^2 / G)`` with ``s`` the noise estimate and ``G``
        the Gauss-Newton curvature
        (:func:`wavemeter.calibration.models.linear_map.delay_information`),
        i.e. ``var(tau) = 2 s^2 / (N J''(tau))``.
    map_ : ndarray, shape (n, 3) or (n, 4)
        Least-squares map at ``delay_s`` (W); with ``affine`` a fourth column of offsets.
    cost : float
        ``J`` at ``delay_s`` (W^2).
    noise_std_w : float
        Detector noise estimate (W): ``sqrt(N J / (N n - 3 n - 1))``, the residual corrected
        for the ``3 n + 1`` fitted values.
    search : DelaySearchResult
        Scan and refinement of ``J(tau)``.
    """

    delay_s: float
    delay_std_s: float | None
    map_: np.ndarray
    cost: float
    noise_std_w: float
    search: DelaySearchResult


def fit_learned_map(
    powers: np.ndarray,
    frequency_hz: np.ndarray,
    center_hz: float,
    *,
    fsr_hz: float,
    fsr_tolerance: float,
    scale=None,
    search: str = "golden",
    xtol: float = 1e-12,
    affine: bool = False,
) -> LearnedFit:
    """Search the delay minimising ``J`` and fit the map there (paper Section II.C).

    One pass accumulates the sweep's moments (:class:`~wavemeter.calibration.models.moments.
    FringeMoments`); the delay search runs on them
    (:func:`~wavemeter.calibration.models.moments.search_moment_delay`), so its time does not grow
    with ``N``; the map and ``J`` at the delay found are one direct least-squares fit.

    Parameters
    ----------
    powers : ndarray, shape (N, n)
        Validated calibration readings (W).
    frequency_hz : ndarray, shape (N,)
        Known frequencies (Hz).
    center_hz : float
        Phase origin (Hz).
    fsr_hz, fsr_tolerance : float
        Design FSR (Hz) and the relative half width of the bracket searched.
    scale : None or ndarray, shape (N,)
        Relative monitored source power per reading.
    search : {"golden", "brent"}
        Refinement of the delay after the scan.
    xtol : float
        Relative tolerance on the delay.
    affine : bool
        Fit per-port offsets too (a fourth map column); needs a varying ``scale``.

    Returns
    -------
    LearnedFit
    """
    moments = FringeMoments(largest_search_delay_s(fsr_hz, fsr_tolerance), center_hz)
    result = search_moment_delay(
        moments.add(frequency_hz, powers, scale),
        fsr_hz=fsr_hz,
        fsr_tolerance=fsr_tolerance,
        method=search,
        xtol=xtol,
        affine=affine,
    )
    objects = object_vectors(frequency_hz, center_hz, result.delay_s, scale, affine)
    matrix, cost_value = map_cost(objects, powers)
    return learned_fit(moments, result, matrix, cost_value)


def fit_learned_map_chunks(
    chunks,
    center_hz: float,
    *,
    fsr_hz: float,
    fsr_tolerance: float,
    search: str = "golden",
    xtol: float = 1e-12,
    affine: bool = False,
) -> LearnedFit:
    """:func:`fit_learned_map` on a sweep read in chunks, in memory bounded by the chunk.

    Each chunk is binned into the sweep's moments
    (:class:`~wavemeter.calibration.models.moments.FringeMoments`) and dropped; everything else
    comes from them. Nothing else is checked (no FSR guard, port health or misfit report:
    those need the readings).

    Parameters
    ----------
    chunks : iterable of (frequency_hz, powers_w, scale)
        ``frequency_hz`` (N_c,) in Hz, ``powers_w`` (N_c, n) in W, ``scale`` (N_c,) the
        monitored source power in any linear unit or None (the same for every chunk); any
        order, any sizes.
    center_hz : float
        Phase origin (Hz), e.g. the middle of the sweep.
    fsr_hz, fsr_tolerance, search, xtol, affine
        As for :func:`fit_learned_map`.

    Returns
    -------
    LearnedFit
        ``delay_s`` as :func:`fit_learned_map` finds it (the same search on the same
        moments); ``map_`` the least-squares map from the moments' normal equations, for
        the monitored power relative to its mean over all chunks (as
        :class:`Calibrator` uses it); ``cost`` ``J`` from the moments, whose absolute error
        is a few ``2^-53 sum |p|^2 / N`` (about ``1e-9 J`` at Table 1 noise);
        ``noise_std_w`` and ``delay_std_s`` from these.

    Raises
    ------
    InputError
        For a malformed chunk, fewer than ``MIN_SAMPLES`` readings in all, or as
        :func:`fit_learned_map`.
    EdgeMinimumError
        As :func:`fit_learned_map`.
    """
    moments = FringeMoments(largest_search_delay_s(fsr_hz, fsr_tolerance), center_hz)
    for frequency, readings, monitor in chunks:
        moments.add(frequency, readings, monitor)
    if moments.samples < MIN_SAMPLES:
        raise InputError(f"need at least {MIN_SAMPLES} samples, got {moments.samples}")
    fit = moment_fit(
        moments, fsr_hz=fsr_hz, fsr_tolerance=fsr_tolerance, search=search, xtol=xtol, affine=affine
    )
    return dataclasses.replace(fit, map_=relative_map(fit.map_, moments.mean_scale))


def moment_fit(
    moments: FringeMoments, *, fsr_hz, fsr_tolerance, search, xtol, affine
) -> LearnedFit:
    """The fit on the moments alone (settings as :func:`fit_learned_map` takes them): the
    search, the map from the normal equations (for the scale as the moments were given it)
    and ``J`` from the moments."""
    result = search_moment_delay(
        moments,
        fsr_hz=fsr_hz,
        fsr_tolerance=fsr_tolerance,
        method=search,
        xtol=xtol,
        affine=affine,
    )
    return learned_fit(moments, result, moments.map_at(result.delay_s, affine), result.cost)


def relative_map(matrix: np.ndarray, mean_scale: float) -> np.ndarray:
    """A map for a monitor in any unit (n, k) as the map for the monitor relative to its mean."""
    relative = matrix.copy()
    relative[:, :3] *= mean_scale
    return relative


def gram_objects(moments: FringeMoments, delay_s: float, affine: bool, mean_scale: float):
    """Stand-ins (2k, k) for the sweep's objects ``X`` and their delay derivative ``D``
    (for the monitor relative to its mean): the products ``X^T X``, ``X^T D``, ``D^T D``
    of every reading, from the moments, as those of ``2 k`` rows.

    The covariance of the fit (:func:`~wavemeter.model.uncertainty.fit_parameter_covariance`)
    depends on the sweep only through these products: any rows with the same Gram matrix
    give it. They are a square root of that matrix, taken from the eigenvectors of its
    correlation matrix (the entries differ by many decades in scale).
    """
    xx, dx, dd = moments.object_gram(delay_s, affine)
    columns = xx.shape[0]
    gram = np.block([[xx, dx.T], [dx, dd]])
    relative = np.ones(2 * columns)
    relative[:3] = relative[columns : columns + 3] = 1.0 / mean_scale
    gram *= np.outer(relative, relative)
    norm = np.sqrt(np.diag(gram))
    norm[norm == 0] = 1.0
    values, vectors = np.linalg.eigh(gram / np.outer(norm, norm))
    root = np.sqrt(np.clip(values, 0.0, None))[:, None] * vectors.T * norm
    return root[:, :columns], root[:, columns:]


def learned_fit(
    moments: FringeMoments, result: DelaySearchResult, matrix: np.ndarray, cost_value: float
) -> LearnedFit:
    """The fit at the searched delay: noise from ``J``, the delay's standard error."""
    ports = matrix.shape[0]
    dof = max(moments.samples * ports - matrix.size - 1, 1)
    noise = float(np.sqrt(cost_value * moments.samples / dof))
    information = moments.delay_information(result.delay_s, matrix)
    return LearnedFit(
        delay_s=result.delay_s,
        delay_std_s=noise / np.sqrt(information) if information > 0 else None,
        map_=matrix,
        cost=cost_value,
        noise_std_w=noise,
        search=result,
    )

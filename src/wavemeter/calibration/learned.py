"""The learned calibration of the paper (Section II.C): closed-form map, 1-D delay search.

For a trial delay ``tau`` the object vectors ``x_k = m_k [cos t_k, sin t_k, sqrt 2]``
(``t_k = 2 pi (f_k - f0) tau``, ``m_k`` the monitored power or 1) are known, and the map
minimising ``J = mean ||p_k - A x_k||^2`` is the linear least-squares solution
``A = Ryx Rxx^-1`` (Eq. 20-23), computed here by an orthogonal factorisation of the
``N x 3`` object matrix rather than by inverting ``Rxx``. ``tau`` minimises ``J(tau)``.
Retrieval: ``x_hat = A+ p``, ``t = atan2(x_hat_2, x_hat_1)``, ``f = f0 + t / (2 pi tau)``.

The pure functions here and the :class:`Calibrator` methods compute the same numbers.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from ..model.cone import cone_vectors, delay_phase_rad, phase_to_frequency_hz
from ..model.limits import crlb_frequency_std
from ..model.retrieval import cone_ml_phase_rad, source_power_ratio
from ..validation import check_choice, check_positive
from .base import BaseCalibrator
from .delay_search import SEARCH_METHODS, search_delay

RETRIEVALS = ("pinv", "ml")

__all__ = [
    "Calibrator",
    "RETRIEVALS",
    "object_vectors",
    "fit_map",
    "map_cost",
    "unfitted_cost",
    "retrieve_phase_rad",
    "predict_frequency_hz",
]


def object_vectors(frequency_hz, center_hz: float, delay_s: float, scale=None) -> np.ndarray:
    """Object vectors (N, 3) for known frequencies under a trial delay.

    ``scale`` is the power monitor reading per sample (any linear unit) or None for a
    constant source power.
    """
    phase = delay_phase_rad(frequency_hz, center_hz, delay_s)
    return cone_vectors(phase, 1.0 if scale is None else scale)


def fit_map(objects: np.ndarray, powers: np.ndarray) -> np.ndarray:
    """Least-squares map ``A`` (n, 3) with ``powers ~ objects @ A.T`` (Eq. 23).

    Solved by a rank-revealing QR factorisation of ``objects`` (LAPACK ``gelsy``).
    """
    solution, *_ = linalg.lstsq(objects, powers, lapack_driver="gelsy", check_finite=False)
    return solution.T


def map_cost(objects: np.ndarray, powers: np.ndarray) -> tuple[np.ndarray, float]:
    """Fitted map and its cost ``J = mean_k ||p_k - A x_k||^2`` (Eq. 20), W^2.

    The residual is formed explicitly (not from ``|p|^2 - |Q^T p|^2``) so that ``J`` keeps
    full relative precision down to noiseless data.
    """
    matrix = fit_map(objects, powers)
    residual = powers - objects @ matrix.T
    return matrix, float(np.einsum("ij,ij->", residual, residual) / powers.shape[0])


def unfitted_cost(powers: np.ndarray, scale=None) -> float:
    """Cost ``J`` (W^2) of the model with no fringe: readings proportional to the power.

    The least-squares fit keeps only the cone-axis column ``sqrt(2) m_k`` (``m_k`` the
    relative monitored power, or 1), i.e. the readings about their (power-weighted) mean.
    A fit at the true delay removes nearly all of this; a side minimum of ``J`` only a
    little (:func:`wavemeter.delay_search.check_fringes_explained`).
    """
    axis = object_vectors(np.zeros(powers.shape[0]), 0.0, 0.0, scale)[:, 2:]
    return map_cost(axis, powers)[1]


def retrieve_phase_rad(powers, map_pinv: np.ndarray) -> np.ndarray:
    """Phase ``atan2(x_hat_2, x_hat_1)`` (rad) of ``x_hat = A+ p`` for readings (N, n)."""
    readings = np.asarray(powers, dtype=float)
    # two matrix-vector products keep both quadratures contiguous for the arctangent
    return np.arctan2(readings @ map_pinv[1], readings @ map_pinv[0])


def predict_frequency_hz(powers, map_: np.ndarray, center_hz: float, fsr_hz: float) -> np.ndarray:
    """Frequency (Hz) of readings (N, n) under a map (n, 3): pinv, arctangent, FSR scale."""
    return phase_to_frequency_hz(retrieve_phase_rad(powers, linalg.pinv(map_)), center_hz, fsr_hz)


class Calibrator(BaseCalibrator):
    """Learned linear-map calibration of an n-port interferometric wavelength meter.

    Parameters
    ----------
    fsr_hz : float
        Design free spectral range (Hz); the delay search brackets it.
    fsr_tolerance : float
        Relative half width of the FSR bracket, in (0, 1). Default 0.2 (+-20 %).
    search : {"golden", "brent"}
        Refinement of the delay after the scan: golden-section (paper) or bounded Brent.
    xtol : float
        Relative tolerance on the delay.
    retrieval : {"pinv", "ml"}
        Phase retrieval: the paper's pseudo-inverse and arctangent, or the cone-constrained
        maximum-likelihood phase (:mod:`wavemeter.retrieval`), which starts from it and
        reaches the Cramer-Rao bound also for ill-conditioned maps.

    Attributes
    ----------
    map_ : ndarray, shape (n, 3)
        Learned map ``A`` (W): readings at the calibration's source power (or, with a
        monitor, per unit of the mean monitor reading) are ``A @ [cos t, sin t, sqrt 2]``.
    map_pinv_ : ndarray, shape (3, n)
        Moore-Penrose inverse of ``map_``.
    delay_s_ : float
        Fitted delay imbalance ``tau`` (s).
    fsr_hz_ : float
        Calibrated FSR ``1 / tau`` (Hz).
    center_hz_ : float
        Phase origin (Hz): the middle of the calibration sweep.
    span_hz_ : (float, float)
        Lowest and highest calibration frequency (Hz).
    residual_rms_ : float
        RMS of the fit residual over all readings (W).
    noise_std_w_ : float
        Detector noise estimate (W): residual corrected for the ``3 n + 1`` fitted values.
    cost_ : float
        ``J`` at the fitted delay (W^2).
    delay_search_ : DelaySearchResult
        Scan and refinement of ``J(tau)`` (not saved to file).
    calibration_rms_hz_ : float
        RMS frequency error on the calibration sweep itself (Hz).
    """

    method = "learned"
    capabilities = frozenset({"frequency_std", "power_monitor"})

    def __init__(
        self,
        fsr_hz: float = 50e9,
        fsr_tolerance: float = 0.2,
        search: str = "golden",
        xtol: float = 1e-12,
        retrieval: str = "pinv",
    ):
        self.fsr_hz = fsr_hz
        self.fsr_tolerance = fsr_tolerance
        self.search = search
        self.xtol = xtol
        self.retrieval = retrieval

    def _check_params(self) -> None:
        super()._check_params()
        check_positive("fsr_tolerance", self.fsr_tolerance, upper=1.0)
        check_choice("search", self.search, SEARCH_METHODS)
        check_positive("xtol", self.xtol, upper=1.0)
        check_choice("retrieval", self.retrieval, RETRIEVALS)

    def _fit(self, powers, frequency_hz, monitor):
        scale = None if monitor is None else monitor / monitor.mean()
        center = self.center_hz_

        def cost(delay_s: float) -> float:
            return map_cost(object_vectors(frequency_hz, center, delay_s, scale), powers)[1]

        result = search_delay(
            cost,
            fsr_hz=self.fsr_hz,
            fsr_tolerance=self.fsr_tolerance,
            span_hz=self.span_hz_[1] - self.span_hz_[0],
            method=self.search,
            xtol=self.xtol,
            unfitted_cost=unfitted_cost(powers, scale),
        )
        matrix, cost_value = map_cost(
            object_vectors(frequency_hz, center, result.delay_s, scale), powers
        )
        samples, ports = powers.shape
        dof = max(samples * ports - 3 * ports - 1, 1)
        self.delay_search_ = result
        self.delay_s_ = result.delay_s
        self.fsr_hz_ = 1.0 / result.delay_s
        self.cost_ = cost_value
        self.residual_rms_ = float(np.sqrt(cost_value / ports))
        self.noise_std_w_ = float(np.sqrt(cost_value * samples / dof))
        self._set_map(matrix)

    def _set_map(self, matrix: np.ndarray) -> None:
        self.map_ = matrix
        self.map_pinv_ = linalg.pinv(matrix)

    def _phase(self, powers):
        phase = retrieve_phase_rad(powers, self.map_pinv_)
        if self.retrieval == "ml":
            phase = cone_ml_phase_rad(powers, self.map_, phase)
        return phase

    def frequency_std_hz(
        self, powers, *, coarse_hz=None, temperature_k=None, phase_rad=None
    ) -> np.ndarray:
        """Per-reading frequency uncertainty (Hz): the Cramer-Rao bound at the reading.

        Evaluated at the retrieved phase (or ``phase_rad``) and the reading's own source
        power, with the detector noise ``noise_std_w_`` estimated from the calibration
        residual. The ``"ml"`` retrieval attains it; the pseudo-inverse may exceed it for
        an ill-conditioned map.

        Parameters
        ----------
        powers : array_like, shape (N, n) or (n,)
        coarse_hz, temperature_k : None, float or array_like, shape (N,)
            Accepted for the common prediction API; not needed by this calibrator.
        phase_rad : None or array_like, shape (N,)
            Phase (rad, zero at ``center_hz_``) to evaluate the bound at, e.g. that of the
            true frequency in an evaluation; default: the retrieved phase.

        Returns
        -------
        ndarray, shape (N,), Hz
        """
        readings = self._check_readings(powers)
        self._check_reading_inputs(readings.shape[0], coarse_hz, temperature_k)
        phase = self._phase(readings) if phase_rad is None else np.asarray(phase_rad, float)
        power = source_power_ratio(readings, self.map_, phase)
        # the bound is linear in the noise: evaluate at unit noise, then scale
        unit = crlb_frequency_std(self.map_, phase, power, 1.0, self.fsr_hz_)
        return unit * self.noise_std_w_

    def _state(self) -> dict:
        return {
            "map": self.map_.tolist(),
            "delay_s": self.delay_s_,
            "cost_w2": self.cost_,
            "residual_rms_w": self.residual_rms_,
            "noise_std_w": self.noise_std_w_,
        }

    def _set_state(self, state: dict) -> None:
        self._set_map(np.array(state["map"], dtype=float))
        self.delay_s_ = float(state["delay_s"])
        self.cost_ = float(state["cost_w2"])
        self.residual_rms_ = float(state["residual_rms_w"])
        self.noise_std_w_ = float(state["noise_std_w"])

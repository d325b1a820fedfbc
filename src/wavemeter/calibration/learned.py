"""The learned calibration of the paper (Section II.C): closed-form map, 1-D delay search.

For a trial delay ``tau`` the map ``A`` is a linear least-squares fit to the sweep
(:mod:`wavemeter.calibration.linear_map`, Eq. 20-23); ``tau`` minimises ``J(tau)``
(:mod:`wavemeter.calibration.delay_search`). Retrieval: ``x_hat = A+ p``,
``t = atan2(x_hat_2, x_hat_1)``, ``f = f0 + t / (2 pi tau)``.

The standard error of the delay follows from the curvature of ``J`` at its minimum and
the noise estimate ``s``: ``var(tau) = 2 s^2 / (N J''(tau))`` (Gauss-Newton, map profiled
out), and ``sigma_FSR = FSR^2 sigma_tau``.

The pure functions here and the :class:`Calibrator` methods compute the same numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg

from ..model.cone import phase_to_frequency_hz
from ..model.limits import crlb_frequency_std
from ..model.retrieval import cone_ml_phase_rad, source_power_ratio
from ..validation import check_choice, check_positive
from .base import BaseCalibrator
from .delay_search import SEARCH_METHODS, DelaySearchResult, search_delay
from .files import state_array, state_float
from .linear_map import delay_information, fit_map, map_cost, object_vectors, unfitted_cost
from .summary import FitValue

RETRIEVALS = ("pinv", "ml")

__all__ = [
    "Calibrator",
    "LearnedFit",
    "RETRIEVALS",
    "fit_learned_map",
    "object_vectors",
    "fit_map",
    "map_cost",
    "unfitted_cost",
    "retrieve_phase_rad",
    "predict_frequency_hz",
]


def retrieve_phase_rad(powers, map_pinv: np.ndarray) -> np.ndarray:
    """Phase ``atan2(x_hat_2, x_hat_1)`` (rad) of ``x_hat = A+ p`` for readings (N, n)."""
    readings = np.asarray(powers, dtype=float)
    # two matrix-vector products keep both quadratures contiguous for the arctangent
    return np.arctan2(readings @ map_pinv[1], readings @ map_pinv[0])


def predict_frequency_hz(powers, map_: np.ndarray, center_hz: float, fsr_hz: float) -> np.ndarray:
    """Frequency (Hz) of readings (N, n) under a map (n, 3): pinv, arctangent, FSR scale."""
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
        the Gauss-Newton curvature (:func:`wavemeter.calibration.linear_map.delay_information`),
        i.e. ``var(tau) = 2 s^2 / (N J''(tau))``.
    map_ : ndarray, shape (n, 3)
        Least-squares map at ``delay_s`` (W).
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
) -> LearnedFit:
    """Search the delay minimising ``J`` and fit the map there (paper Section II.C).

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

    Returns
    -------
    LearnedFit
    """

    def cost(delay_s: float) -> float:
        return map_cost(object_vectors(frequency_hz, center_hz, delay_s, scale), powers)[1]

    result = search_delay(
        cost,
        fsr_hz=fsr_hz,
        fsr_tolerance=fsr_tolerance,
        span_hz=float(np.ptp(frequency_hz)),
        method=search,
        xtol=xtol,
        unfitted_cost=unfitted_cost(powers, scale),
    )
    matrix, cost_value = map_cost(
        object_vectors(frequency_hz, center_hz, result.delay_s, scale), powers
    )
    samples, ports = powers.shape
    dof = max(samples * ports - 3 * ports - 1, 1)
    noise = float(np.sqrt(cost_value * samples / dof))
    information = delay_information(frequency_hz, center_hz, result.delay_s, matrix, scale)
    return LearnedFit(
        delay_s=result.delay_s,
        delay_std_s=noise / np.sqrt(information) if information > 0 else None,
        map_=matrix,
        cost=cost_value,
        noise_std_w=noise,
        search=result,
    )


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
    delay_std_s_ : float or None
        Standard error of ``delay_s_`` (s); None when loaded from a file of version 0.1.
        The FSR's is ``fsr_hz_**2 * delay_std_s_`` (``summary()["fsr_hz"].stderr``).
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
    diagnostics_ : dict
        The sweep's own FSR estimate, every port's fringe amplitude and significance, and
        the warnings the fit emitted (saved to file).
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

    def _fsr_tolerance(self) -> float:
        return self.fsr_tolerance

    def _fit(self, powers, frequency_hz, monitor):
        fit = fit_learned_map(
            powers,
            frequency_hz,
            self.center_hz_,
            fsr_hz=self.fsr_hz,
            fsr_tolerance=self.fsr_tolerance,
            scale=None if monitor is None else monitor / monitor.mean(),
            search=self.search,
            xtol=self.xtol,
        )
        self.delay_search_ = fit.search
        self.delay_s_ = fit.delay_s
        self.delay_std_s_ = fit.delay_std_s
        self.fsr_hz_ = 1.0 / fit.delay_s
        self.cost_ = fit.cost
        self.residual_rms_ = float(np.sqrt(fit.cost / powers.shape[1]))
        self.noise_std_w_ = fit.noise_std_w
        self._set_map(fit.map_)

    def _fsr_std_hz(self) -> float | None:
        """``FSR^2 sigma_tau`` (Hz); None for a file of 0.1, which did not keep it."""
        return None if self.delay_std_s_ is None else self.fsr_hz_**2 * self.delay_std_s_

    def _summary_values(self) -> dict:
        return {
            "delay_s": FitValue(self.delay_s_, self.delay_std_s_, "s"),
            "noise_std_w": FitValue(self.noise_std_w_, None, "W"),
            "cost_w2": FitValue(self.cost_, None, "W^2"),
        }

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
        readings, _ = self._check_reading_data(powers, coarse_hz, temperature_k)
        phase = self._phase(readings) if phase_rad is None else np.asarray(phase_rad, float)
        power = source_power_ratio(readings, self.map_, phase)
        # the bound is linear in the noise: evaluate at unit noise, then scale
        unit = crlb_frequency_std(self.map_, phase, power, 1.0, self.fsr_hz_)
        return unit * self.noise_std_w_

    def _state(self) -> dict:
        return {
            "map": self.map_.tolist(),
            "delay_s": self.delay_s_,
            "delay_std_s": self.delay_std_s_,
            "cost_w2": self.cost_,
            "residual_rms_w": self.residual_rms_,
            "noise_std_w": self.noise_std_w_,
        }

    def _set_state(self, state: dict) -> None:
        self._set_map(state_array(state, "map", (self.n_ports_, 3)))
        self.delay_s_ = state_float(state, "delay_s", minimum=0.0, open_minimum=True)
        # files of 0.1 have no standard error of the delay
        self.delay_std_s_ = (
            state_float(state, "delay_std_s", minimum=0.0)
            if state.get("delay_std_s") is not None
            else None
        )
        self.cost_ = state_float(state, "cost_w2", minimum=0.0)
        self.residual_rms_ = state_float(state, "residual_rms_w", minimum=0.0)
        self.noise_std_w_ = state_float(state, "noise_std_w", minimum=0.0)

"""Kleijn's nonlinear least-squares fit of the physical MZI model (n-port generalisation).

Kleijn, Smit and Leijtens (J. Lightwave Technol., 3x3-MMI wavelength meter) model port
``j`` as ``p_j = S (m_aj^2 + m_bj^2 + 2 m_aj m_bj cos(t - phi_j))``, ``S`` the sum of the
port powers of each sample. :class:`NonlinearFitCalibrator` fits all ``3 n + 1``
parameters (magnitudes, port phases, delay) together by Levenberg-Marquardt from the
design values (:func:`design_parameters`) and inverts the fitted model per sample by
Newton steps. Where the port sum is not proportional to the source power (a non-ideal
coupler, unequal receivers) the model is wrong and the fit biased even without noise.
:func:`convergence_share` counts how often random starts converge (for benchmarks).

Theory (the model, the retrieval, the convergence study): the docs' baselines page
(``docs/theory/baselines.rst``, "Kleijn's nonlinear fit").
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import linalg, optimize

from ....exceptions import InputError
from ....model.couplers import mmi_matrix, port_phases_rad
from ....validation import as_rng, check_positive
from ...contract.base import MAX_MAP_CONDITION, BaseCalibrator
from ...contract.summary import FitValue
from ...files import fields
from ...files.document import state_array, state_float
from ...fitting.steps import SweepFitMixin
from ._compared import ComparedWithLearnedMixin

__all__ = [
    "ConvergenceShare",
    "NonlinearFitCalibrator",
    "NonlinearFitWarning",
    "convergence_share",
    "design_parameters",
]

#: Newton refinements of the per-sample phase after the unconstrained start
NEWTON_STEPS = 3
#: relative tolerances of the Levenberg-Marquardt fit (ftol, xtol, gtol)
FIT_TOLERANCE = 1e-12


class NonlinearFitWarning(RuntimeWarning):
    """The nonlinear least-squares fit stopped without meeting its tolerances."""


#: largest scattering magnitude a calibration file may hold: ``(m_a + m_b)^2`` is a port's
#: share of the total power, near 1 at most; 10 allows 400 times that
MAX_MAGNITUDE = 10.0


def design_parameters(ports: int, fsr_hz: float = 50e9, inputs=(0, 2)) -> np.ndarray:
    """Design starting point ``[m_a (n), m_b (n), phi (n), delay_s]`` of the fit.

    Parameters
    ----------
    ports : int
        Number of output ports ``n >= 3``.
    fsr_hz : float
        Design FSR (Hz); the delay is ``1 / fsr_hz``.
    inputs : (int, int)
        Zero-based MMI ingress ports fed by the delayed and the other arm.

    Returns
    -------
    ndarray, shape (3 n + 1,)
        Magnitudes ``1 / sqrt(2 n)`` (dimensionless), ideal-MMI port phases (rad), delay (s).

    Notes
    -----
    The phase common to all ports (the splitter's phase and the bias, unknown before the
    fit) is left at zero; the fitted port phases absorb it.
    """
    check_positive("fsr_hz", fsr_hz)
    phases = port_phases_rad(mmi_matrix(ports), tuple(inputs))
    magnitudes = np.full(2 * ports, 1.0 / np.sqrt(2.0 * ports))
    return np.concatenate([magnitudes, phases, [1.0 / fsr_hz]])


def _fringes(magnitudes: np.ndarray, phases_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Offsets ``c`` (n,) and fringe matrix ``B`` (n, 2) of per-unit-``S`` port powers."""
    delayed, other = magnitudes[:, 0], magnitudes[:, 1]
    amplitude = 2.0 * delayed * other
    return delayed**2 + other**2, np.column_stack(
        [amplitude * np.cos(phases_rad), amplitude * np.sin(phases_rad)]
    )


class _Model:
    """Residuals and Jacobian of Kleijn's model on one sweep, in ``(m_a, m_b, phi, u)``.

    ``u = tau fsr_hz`` is the delay relative to design, so that all parameters are O(1).
    """

    def __init__(self, powers, frequency_hz, center_hz, fsr_hz):
        self.powers = powers
        self.total = powers.sum(axis=1)
        self.scale = self.total.mean()
        self.design_phase = 2.0 * np.pi * (frequency_hz - center_hz) / fsr_hz
        self.ports = powers.shape[1]

    def split(self, theta):
        n = self.ports
        return theta[:n], theta[n : 2 * n], theta[2 * n : 3 * n], theta[3 * n]

    def residuals(self, theta) -> np.ndarray:
        delayed, other, phases, u = self.split(theta)
        cosine = np.cos(u * self.design_phase[:, None] - phases)
        model = delayed**2 + other**2 + 2.0 * delayed * other * cosine
        return ((self.powers - self.total[:, None] * model) / self.scale).ravel()

    def jacobian(self, theta) -> np.ndarray:
        delayed, other, phases, u = self.split(theta)
        argument = u * self.design_phase[:, None] - phases
        cosine, sine = np.cos(argument), np.sin(argument)
        weight = -(self.total / self.scale)[:, None]  # d residual / d model
        samples, n = cosine.shape
        jac = np.zeros((samples, n, 3 * n + 1))
        ports = np.arange(n)
        jac[:, ports, ports] = weight * (2.0 * delayed + 2.0 * other * cosine)
        jac[:, ports, n + ports] = weight * (2.0 * other + 2.0 * delayed * cosine)
        jac[:, ports, 2 * n + ports] = weight * (2.0 * delayed * other * sine)
        jac[:, :, 3 * n] = weight * (-2.0 * delayed * other * sine * self.design_phase[:, None])
        return jac.reshape(samples * n, 3 * n + 1)


class NonlinearFitCalibrator(ComparedWithLearnedMixin, SweepFitMixin, BaseCalibrator):
    """Kleijn's nonlinear least-squares calibration of the physical MZI model.

    Parameters
    ----------
    fsr_hz : float
        Design FSR (Hz): the starting delay ``1 / fsr_hz``.
    initial : None or array_like, shape (3 n + 1,)
        Starting point ``[m_a (n), m_b (n), phi (n) in rad, delay_s]``; default
        :func:`design_parameters`.
    max_nfev : int
        Largest number of model evaluations of the fit.

    Attributes
    ----------
    magnitudes_ : ndarray, shape (n, 2)
        Fitted scattering magnitudes (delayed arm, other arm) per port, per unit of ``S``
        (dimensionless).
    port_phases_rad_ : ndarray, shape (n,)
        Fitted port phases (rad), bias included: port ``j`` peaks at ``t = phi_j``.
    delay_s_ : float
        Fitted delay (s); ``fsr_hz_ = 1 / delay_s_``.
    converged_ : bool
        Whether the fit met its tolerances (``least_squares`` status > 0). A fit that did
        not converge is kept, with a :class:`NonlinearFitWarning`.
    fit_status_ : int
        ``least_squares`` status: 0 evaluation budget spent, 1-4 converged (gtol, ftol,
        xtol, ftol and xtol).
    fit_message_ : str
        ``least_squares`` message.
    nfev_ : int
        Model evaluations used.
    fringe_offsets_ : ndarray, shape (n,)
        Fringe offsets ``c_j = m_aj^2 + m_bj^2`` per unit of ``S``.
    fringe_matrix_ : ndarray, shape (n, 2)
        ``B = [a cos phi, a sin phi]`` with ``a_j = 2 m_aj m_bj``, per unit of ``S``.
    cost_ : float
        Mean over samples of the squared residual norm ``|p - S model|^2`` (W^2), the same
        measure as :attr:`wavemeter.Calibrator.cost_`.
    fsr_hz_, center_hz_, span_hz_, calibration_rms_hz_ : see :class:`wavemeter.Calibrator`.

    Examples
    --------
    >>> import numpy as np
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> cal = wm.NonlinearFitCalibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> print(f"fitted FSR {cal.fsr_hz_ / 1e9:.2f} GHz, true {device.true_fsr_hz / 1e9:.2f} GHz")
    fitted FSR 51.25 GHz, true 51.50 GHz

    The sum of the port powers is not the source power on an impaired coupler, so the
    physical model is biased here: its FSR is 250 MHz off the true 51.50 GHz and its
    error several times the learned map's 17 MHz:

    >>> test_hz = f_hz[5::20] + 1e8
    >>> test = device.powers(test_hz, power_w=1e-3, noise_w=5e-7, rng=2)
    >>> print(f"RMS error {np.sqrt(np.mean((cal.predict(test) - test_hz) ** 2)) / 1e6:.0f} MHz")
    RMS error 106 MHz
    """

    method = "nonlinear_fit"
    #: the model is per unit of total power: the power scale is the sweep's (reading model)
    state_rules = fields.rule_table(
        {
            "magnitudes": fields.FieldRule("a scattering magnitude", "", 0.0, MAX_MAGNITUDE),
            "port_phases_rad": fields.ANGLE_RULE,
            "delay_s": fields.DELAY_RULE,
            "fit_status": fields.FieldRule("the solver's status", "", -1, 4, integer=True),
            "nfev": fields.FieldRule("the model evaluations", "", 0, 1e9, integer=True),
            "cost_w2": fields.COST_RULE,
        }
    )

    def __init__(self, fsr_hz: float = 50e9, initial=None, max_nfev: int = 1000):
        self.fsr_hz = fsr_hz
        self.initial = initial
        self.max_nfev = max_nfev

    def _check_params(self) -> None:
        super()._check_params()
        if (
            isinstance(self.max_nfev, bool)
            or not isinstance(self.max_nfev, (int, np.integer))
            or self.max_nfev < 1
        ):
            raise InputError(f"max_nfev must be an integer >= 1, got {self.max_nfev!r}")

    def _starting_point(self, ports: int) -> np.ndarray:
        if self.initial is None:
            return design_parameters(ports, self.fsr_hz)
        start = np.array(self.initial, dtype=float)
        if start.shape != (3 * ports + 1,) or not np.all(np.isfinite(start)):
            raise InputError(
                f"initial must be 3 n + 1 = {3 * ports + 1} finite numbers [m_a (n), m_b (n), "
                f"phi (n), delay_s] for n = {ports} ports, got shape {start.shape}"
            )
        if not start[-1] > 0:
            raise InputError(f"initial delay_s (last entry) must be > 0, got {start[-1]!r}")
        return start

    def _learn(self, sweep):
        powers, frequency_hz, monitor = sweep.powers_w, sweep.frequency_hz, sweep.monitor_w
        if monitor is not None:
            raise InputError(
                "power_monitor_w is not used by the nonlinear_fit method (Kleijn's model takes "
                "the source power as the sum of the port powers); pass power_monitor_w=None"
            )
        n = powers.shape[1]
        model = _Model(powers, frequency_hz, self.center_hz_, self.fsr_hz)
        start = self._starting_point(n)
        start[-1] *= self.fsr_hz  # delay (s) -> relative delay u
        result = optimize.least_squares(
            model.residuals,
            start,
            jac=model.jacobian,
            method="lm",
            ftol=FIT_TOLERANCE,
            xtol=FIT_TOLERANCE,
            gtol=FIT_TOLERANCE,
            max_nfev=int(self.max_nfev),
        )
        delayed, other, phases, u = model.split(result.x)
        self.converged_ = bool(result.success)
        self.fit_status_ = int(result.status)
        self.fit_message_ = str(result.message)
        self.nfev_ = int(result.nfev)
        self.cost_ = float(2.0 * result.cost * model.scale**2 / powers.shape[0])
        if not self.converged_:
            warnings.warn(
                f"the nonlinear fit did not converge (status {self.fit_status_}: "
                f"{self.fit_message_}); the calibration is kept but is likely wrong: give a "
                "better `initial` or a larger `max_nfev`",
                NonlinearFitWarning,
                stacklevel=3,
            )
        # equivalent parameters, folded to non-negative magnitudes and delay: (m_a, m_b) ->
        # (|m_a|, |m_b|) with phi + pi when m_a m_b < 0, and (u, phi) -> (-u, -phi)
        phases = phases + np.where(delayed * other < 0, np.pi, 0.0)
        phases = np.sign(u) * phases
        self._set_parameters(
            np.abs(np.column_stack([delayed, other])),
            np.angle(np.exp(1j * phases)),
            abs(u) / self.fsr_hz,
        )

    def _set_parameters(self, magnitudes, port_phases_rad, delay_s) -> None:
        """Store the model and the fringes its inversion uses (one path for fit and load)."""
        self.magnitudes_ = magnitudes
        self.port_phases_rad_ = port_phases_rad
        self.delay_s_ = float(delay_s)
        self.fsr_hz_ = 1.0 / self.delay_s_
        self.fringe_offsets_, self.fringe_matrix_ = _fringes(magnitudes, port_phases_rad)

    def _phase(self, powers):
        matrix = self.fringe_matrix_
        relative = powers / powers.sum(axis=1, keepdims=True) - self.fringe_offsets_
        start = relative @ linalg.pinv(matrix).T
        phase = np.arctan2(start[:, 1], start[:, 0])
        for _ in range(NEWTON_STEPS):
            along = np.column_stack([np.cos(phase), np.sin(phase)]) @ matrix.T  # B u
            across = np.column_stack([-np.sin(phase), np.cos(phase)]) @ matrix.T  # B u'
            misfit = relative - along
            slope = -np.einsum("ij,ij->i", misfit, across)  # half of d/dt |misfit|^2
            curvature = np.einsum("ij,ij->i", across, across) + np.einsum("ij,ij->i", misfit, along)
            phase = phase - np.where(curvature > 0, slope / curvature, 0.0)
        return np.angle(np.exp(1j * phase))

    def _summary_values(self) -> dict:
        return {
            "delay_s": FitValue(self.delay_s_, None, "s"),
            "converged": FitValue(float(self.converged_), None, "", "converged (1 yes, 0 no)"),
            "nfev": FitValue(float(self.nfev_), None, "", "cost evaluations"),
            "cost_w2": FitValue(self.cost_, None, "W^2", "cost"),
        }

    def _state(self) -> dict:
        return {
            "magnitudes": self.magnitudes_.tolist(),
            "port_phases_rad": self.port_phases_rad_.tolist(),
            "delay_s": self.delay_s_,
            "converged": self.converged_,
            "fit_status": self.fit_status_,
            "fit_message": self.fit_message_,
            "nfev": self.nfev_,
            "cost_w2": self.cost_,
        }

    def _set_state(self, state: dict) -> None:
        n = self.n_ports_
        magnitudes = state_array(state, "magnitudes", (n, 2))
        phases = state_array(state, "port_phases_rad", (n,))
        delay = state_float(state, "delay_s", minimum=0.0, open_minimum=True)
        converged, message = state.get("converged"), state.get("fit_message")
        if not isinstance(converged, bool) or not isinstance(message, str):
            raise InputError(
                "fields 'converged' (true or false) and 'fit_message' (text) are needed"
            )
        self._set_parameters(magnitudes, phases, delay)
        self.converged_ = converged
        self.fit_status_ = int(state_float(state, "fit_status"))
        self.fit_message_ = message
        self.nfev_ = int(state_float(state, "nfev"))
        self.cost_ = state_float(state, "cost_w2", minimum=0.0)

    def _check_state(self) -> None:
        super()._check_state()
        singular = np.linalg.svd(self.fringe_matrix_, compute_uv=False)
        if not (singular[-1] > 0 and singular[0] / singular[-1] < MAX_MAP_CONDITION):
            raise InputError(
                "fields 'magnitudes' and 'port_phases_rad' must give two independent fringes "
                f"(condition number below {MAX_MAP_CONDITION:g}), got singular values "
                f"{singular.tolist()}"
            )


@dataclass(frozen=True)
class ConvergenceShare:
    """Outcome of :func:`convergence_share`.

    Attributes
    ----------
    share : float
        Fraction of the random starts that converged to the best solution.
    right : ndarray of bool, shape (starts,)
        Per start: converged (status > 0) with a cost within ``cost_rtol`` of the best.
    converged : ndarray of bool, shape (starts,)
        Per start: ``least_squares`` reported convergence (to any minimum).
    cost_w2 : ndarray, shape (starts,)
        Final cost of each start (W^2, see :attr:`NonlinearFitCalibrator.cost_`).
    best_cost_w2 : float
        Smallest converged cost over the design start and all random starts (W^2).
    initial : ndarray, shape (starts, 3 n + 1)
        The starting points, as :class:`NonlinearFitCalibrator` ``initial``.
    """

    share: float
    right: np.ndarray
    converged: np.ndarray
    cost_w2: np.ndarray
    best_cost_w2: float
    initial: np.ndarray


def convergence_share(
    powers,
    frequency_hz,
    *,
    fsr_hz: float = 50e9,
    starts: int = 100,
    spread: float = 0.2,
    max_nfev: int = 1000,
    rng=None,
    cost_rtol: float = 0.01,
) -> ConvergenceShare:
    """Share of random starting points from which the nonlinear fit finds the best solution.

    Parameters
    ----------
    powers : array_like, shape (N, n)
        Calibration readings (W).
    frequency_hz : array_like, shape (N,)
        Known frequencies (Hz).
    fsr_hz : float
        Design FSR (Hz).
    starts : int
        Number of random starting points.
    spread : float
        Relative half width of the starts: magnitudes and delay scaled by
        ``1 + U(-spread, spread)``, port phases shifted by ``pi U(-spread, spread)`` rad.
    max_nfev : int
        Evaluation budget of each fit.
    rng : None, int or numpy.random.Generator
        Source of the starting points.
    cost_rtol : float
        A start is right when it converged and its cost is at most ``(1 + cost_rtol)``
        times the best cost (a wrong local minimum costs far more; symmetric solutions
        such as swapped magnitudes cost the same and predict the same).

    Returns
    -------
    ConvergenceShare
    """
    if isinstance(starts, bool) or not isinstance(starts, (int, np.integer)) or starts < 1:
        raise InputError(f"starts must be an integer >= 1, got {starts!r}")
    spread = check_positive("spread", spread, upper=1.0)
    cost_rtol = check_positive("cost_rtol", cost_rtol)
    generator = as_rng(rng)
    ports = np.shape(powers)[1]
    design = design_parameters(ports, fsr_hz)
    factors = 1.0 + generator.uniform(-spread, spread, (starts, design.size))
    initial = design * factors
    initial[:, 2 * ports : 3 * ports] = design[2 * ports : 3 * ports] + np.pi * generator.uniform(
        -spread, spread, (starts, ports)
    )
    costs, converged = np.empty(starts), np.empty(starts, dtype=bool)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NonlinearFitWarning)
        reference = NonlinearFitCalibrator(fsr_hz, None, max_nfev).fit(powers, frequency_hz)
        for k, start in enumerate(initial):
            fit = NonlinearFitCalibrator(fsr_hz, start, max_nfev).fit(powers, frequency_hz)
            costs[k], converged[k] = fit.cost_, fit.converged_
    candidates = costs[converged]
    if reference.converged_:
        candidates = np.append(candidates, reference.cost_)
    best = float(candidates.min()) if candidates.size else float("inf")
    right = converged & (costs <= (1.0 + cost_rtol) * best)
    return ConvergenceShare(
        share=float(right.mean()),
        right=right,
        converged=converged,
        cost_w2=costs,
        best_cost_w2=best,
        initial=initial,
    )

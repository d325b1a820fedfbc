"""Adapters for the external peers the benchmarks run side by side (optional extras).

hoqi-bench (PyPI ``hoqi-bench``): seven two-channel phase-demodulation methods of
homodyne quadrature interferometry, each a function ``fit(I, Q) -> FitResult`` that fits
and retrieves in one call. :class:`HoqiCalibrator` fits one of them on two ports of a
calibration sweep, keeps its fitted parameters (an ellipse as ``(dc_i, dc_q, g, eps)``, or
a circle centre) to retrieve new readings with hoqi-bench's own correction, and fixes the
phase origin, direction and FSR from the labels like the library's baselines
(:class:`wavemeter.baselines._labels.LabelLockedCalibrator`).

MiniPTI (PyPI ``minipti``): the per-sample phase solver of a passively demodulated 3x3
interferometer (Levenberg-Marquardt fit of ``cos(t - phi_j)`` to the normalised readings,
given MiniPTI's characterisation: per-detector amplitude, offset and output phase). Its
``Interferometer.calculate_phase`` fails on numpy 2 (``np.fromiter`` over the solver's
one-element arrays); :func:`minipti_solver` calls the per-sample solver directly.
MiniPTI 1.9.3 installs its modules at the top level of site-packages (``algorithm``,
``hardware``, ``gui``); :func:`load_minipti` loads ``algorithm/interferometry.py`` from
the files of the installed ``minipti`` distribution, so an unrelated ``algorithm`` module
cannot stand in for it.

Neither peer is a runtime dependency of ``wavemeter``. Every loader raises
:class:`PeerUnavailable` with the reason when its peer cannot be installed or imported;
callers print it and go on.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import importlib.util
from collections.abc import Callable
from types import ModuleType

import numpy as np

from wavemeter.calibration.methods.baselines._labels import LabelLockedCalibrator

__all__ = [
    "HOQI_INSTALL",
    "MINIPTI_INSTALL",
    "HoqiCalibrator",
    "PeerUnavailable",
    "hoqi_fit",
    "hoqi_method_names",
    "hoqi_phase",
    "load_hoqi",
    "load_minipti",
    "minipti_solver",
    "peer_version",
]

HOQI_INSTALL = "pip install --no-deps hoqi-bench"
MINIPTI_INSTALL = "pip install --no-deps minipti && pip install pandas"

#: hoqi-bench method that takes a nominal DC level instead of fitting one
HOQI_RAW = "raw_atan2"


class PeerUnavailable(RuntimeError):
    """An external peer cannot be imported; the message says why and how to install it."""


def peer_version(distribution: str) -> str:
    """Installed version of a distribution, or ``"absent"``."""
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return "absent"


# ---------------------------------------------------------------------------- hoqi-bench
def load_hoqi() -> ModuleType:
    """``hoqi_bench.methods`` (the registry of the seven methods).

    Raises
    ------
    PeerUnavailable
        When hoqi-bench is not installed or does not import.
    """
    try:
        return importlib.import_module("hoqi_bench.methods")
    except ImportError as exc:
        raise PeerUnavailable(f"hoqi-bench not importable ({exc}); {HOQI_INSTALL}") from exc


def hoqi_method_names() -> list[str]:
    """Names of hoqi-bench's phase-recovery methods, in its registry order."""
    return list(load_hoqi().METHOD_REGISTRY)


def hoqi_fit(name: str, intensity_i, intensity_q, mean_intensity: float | None = None) -> dict:
    """Run one hoqi-bench method on two channels; its fitted parameters and phase.

    Parameters
    ----------
    name : str
        Registry name (see :func:`hoqi_method_names`).
    intensity_i, intensity_q : ndarray, shape (N,)
        The two channels (any linear unit).
    mean_intensity : float or None
        Nominal DC level of both channels; used (and required) only by ``raw_atan2``.

    Returns
    -------
    dict
        ``phase_rad`` (ndarray, shape (N,)) and ``params``: ``dc_offset_i``,
        ``dc_offset_q``, ``amplitude_ratio``, ``quadrature_error_rad`` for the ellipse
        methods, ``center_i``, ``center_q`` for the circle methods and ``raw_atan2``.

    Raises
    ------
    ValueError
        When the method reports a failed fit (with hoqi-bench's reason code).
    """
    methods = load_hoqi()
    i, q = np.asarray(intensity_i, dtype=float), np.asarray(intensity_q, dtype=float)
    if name == HOQI_RAW:
        if mean_intensity is None:
            raise ValueError("raw_atan2 needs the nominal DC level mean_intensity")
        result = methods.fit_by_name(name, i, q, mean_intensity=mean_intensity)
        params = {"center_i": mean_intensity, "center_q": mean_intensity}
    else:
        result = methods.METHOD_REGISTRY[name](i, q)
        params = dict(result.params or {})
    if result.failed or not np.all(np.isfinite(result.recovered_phase)):
        raise ValueError(f"hoqi-bench {name} failed: {result.reason or 'non-finite phase'}")
    return {"phase_rad": result.recovered_phase, "params": params}


def hoqi_phase(params: dict, intensity_i, intensity_q) -> np.ndarray:
    """Phase (rad) of new readings under parameters fitted by :func:`hoqi_fit`.

    Ellipse parameters go through hoqi-bench's own Heydemann correction, circle centres
    through ``atan2`` about the centre, as each method does on its fitted data.
    """
    i, q = np.asarray(intensity_i, dtype=float), np.asarray(intensity_q, dtype=float)
    if "quadrature_error_rad" in params:
        ellipse = importlib.import_module("hoqi_bench.methods._ellipse")
        i, q = ellipse.apply_heydemann_correction(
            i,
            q,
            params["dc_offset_i"],
            params["dc_offset_q"],
            params["amplitude_ratio"],
            params["quadrature_error_rad"],
        )
        return np.arctan2(q, i)
    return np.arctan2(q - params["center_q"], i - params["center_i"])


class HoqiCalibrator(LabelLockedCalibrator):
    """One hoqi-bench two-channel method on a port pair, labels fixing origin, sign and FSR.

    hoqi-bench works in units where a channel's DC level is about 1 (its forward model's
    ``mean_intensity`` defaults to 1) and some of its fits are not scale invariant (the
    Koning-Wimmer-Witkovsky conic is unnormalised, with an absolute tolerance), so readings
    are divided by the nominal DC level of a port before hoqi-bench sees them.

    Parameters
    ----------
    fsr_hz : float
        Design FSR (Hz); the sweep refines it within +-20 %.
    name : str
        hoqi-bench method name (see :func:`hoqi_method_names`).
    ports : (int, int)
        Zero-based ports used as the I and Q channels.
    nominal_level_w : float
        Nominal DC level of a port (W): the unit of the channels given to hoqi-bench, and
        the DC level ``raw_atan2`` assumes.

    Attributes
    ----------
    params_ : dict
        The method's fitted parameters, in units of ``nominal_level_w`` (see
        :func:`hoqi_fit`).
    direction_, phase_origin_rad_, fsr_hz_, center_hz_ : see
        :class:`wavemeter.baselines.EllipseCalibrator`.

    Notes
    -----
    A benchmark adapter: it has no calibration-file state, so ``save`` is not supported.
    """

    method = "hoqi"

    def __init__(
        self, fsr_hz: float = 50e9, name: str = "heydemann", ports=(0, 1), nominal_level_w=1.0
    ):
        self.fsr_hz = fsr_hz
        self.name = name
        self.ports = ports
        self.nominal_level_w = nominal_level_w

    def _channels(self, powers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        first, second = self.ports
        return powers[:, first] / self.nominal_level_w, powers[:, second] / self.nominal_level_w

    def _fit(self, powers, frequency_hz, monitor):
        self.params_ = hoqi_fit(self.name, *self._channels(powers), mean_intensity=1.0)["params"]
        self._lock_to_labels(powers, frequency_hz)

    def _raw_phase(self, powers):
        return hoqi_phase(self.params_, *self._channels(powers))


# ---------------------------------------------------------------------------- MiniPTI
def load_minipti() -> ModuleType:
    """MiniPTI's ``algorithm/interferometry.py``, loaded from the ``minipti`` distribution.

    Raises
    ------
    PeerUnavailable
        When minipti is not installed, the file is missing, or it does not import
        (it needs pandas).
    """
    try:
        files = importlib.metadata.distribution("minipti").files or []
    except importlib.metadata.PackageNotFoundError as exc:
        raise PeerUnavailable(f"minipti not installed; {MINIPTI_INSTALL}") from exc
    path = next((f for f in files if f.as_posix() == "algorithm/interferometry.py"), None)
    if path is None:
        raise PeerUnavailable("minipti is installed without algorithm/interferometry.py")
    spec = importlib.util.spec_from_file_location("_minipti_interferometry", path.locate())
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except ImportError as exc:
        raise PeerUnavailable(f"minipti not importable ({exc}); {MINIPTI_INSTALL}") from exc
    return module


def minipti_solver(settings_path) -> Callable[[np.ndarray], np.ndarray]:
    """MiniPTI's per-sample phase solver, set up with a characterisation file.

    Parameters
    ----------
    settings_path : path-like
        MiniPTI characterisation CSV (``Amplitude [V]``, ``Offset [V]``,
        ``Output Phases [deg]`` per detector).

    Returns
    -------
    callable
        ``phase(powers)``: readings (N, 3) in the unit of the characterisation (MiniPTI: V)
        to phase (rad, in [0, 2 pi)), one solver call per reading.
    """
    solver = load_minipti().Interferometer(settings_path=str(settings_path))
    solver.load_settings()

    def phase(powers) -> np.ndarray:
        readings = np.asarray(powers, dtype=float)
        return np.array([solver._calculate_phase(row)[0] for row in readings])

    return phase

"""The learned calibration side by side with its peers, on simulations and on measured data.

Simulated regimes (``_montecarlo.REGIMES``): for each regime, port count (3 and 4) and
device, every method is fitted on the same labelled calibration sweep and retrieves the
same test readings. Methods: the learned ``Calibrator``, Todd's conventional and extended
conventional methods, Kleijn's nonlinear fit, the two-port ellipse, the n-port plane
ellipse, and hoqi-bench's seven two-channel methods when installed. Two-channel methods use
the port pair whose design fringe phases are closest to quadrature; the labels fix only
their phase origin, direction and FSR. Per method: RMS and max error, RMS over the
Cramer-Rao bound of each device's test set, fit time, predict throughput and, for the
nonlinear fit, the share of random starting points that reach the best solution.

Measured data (MiniPTI's 3x3 fiber-coupler record): every reference-free method retrieves
the phase of ``DC CH1..3``; the rms difference from MiniPTI's published phase (after a
constant offset and the sign) and the time per sample are measured in the same run.

Usage: ``python benchmarks/peers.py [--devices 30] [--quick] [--seed 0]``; tables on
stdout (markdown), progress on stderr.
"""

from __future__ import annotations

import argparse
import itertools
import statistics
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from _montecarlo import (
    DESIGN_FSR_HZ,
    NOISE_W,
    POWER_W,
    REGIMES,
    TEST_SAMPLES,
    Regime,
    markdown_table,
    median_time_s,
    progress,
    trials,
)
from external_peers import (
    HoqiCalibrator,
    PeerUnavailable,
    hoqi_fit,
    hoqi_method_names,
    minipti_solver,
    peer_version,
)

import wavemeter as wm
from wavemeter.baselines import (
    EllipseCalibrator,
    ExtendedConventionalCalibrator,
    NonlinearFitCalibrator,
    PlaneEllipseCalibrator,
)
from wavemeter.calibration.methods.baselines.ellipse import ellipse_phase, fit_ellipse
from wavemeter.calibration.methods.baselines.nonlinear_fit import (
    NonlinearFitWarning,
    convergence_share,
)
from wavemeter.calibration.methods.baselines.plane_ellipse import (
    fit_plane_ellipse,
    plane_ellipse_phase,
)

PORTS = (3, 4)
DEFAULT_DEVICES = 30
QUICK_DEVICES = 3
#: random starting points of the nonlinear-fit convergence study, and their spread
STARTS = 100
START_SPREAD = 0.2
#: devices per regime and port count on which the convergence study runs (it costs 100 fits)
CONVERGENCE_DEVICES = 5
PREDICT_REPEATS = 3
MEASURED_REPEATS = 5
MINIPTI_REPEATS = 3
DATA_DIR = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "minipti-fiber-3x3"
MEASURED_PORTS = ("DC CH1", "DC CH2", "DC CH3")
FIT_ERRORS = (ValueError, np.linalg.LinAlgError)

LEARNED = "Learned (Calibrator)"
LEARNED_ML = "Learned, cone ML retrieval"
CONVENTIONAL = "Conventional (Todd)"
EXTENDED = "Extended conventional (Todd)"
NONLINEAR = "Nonlinear fit (Kleijn)"
PLANE = "Plane ellipse"


# ---------------------------------------------------------------------------- methods
@dataclass(frozen=True)
class Method:
    """A calibration method: a name and a factory of an unfitted calibrator for a device."""

    name: str
    make: Callable[[wm.Interferometer], object]


def quadrature_pair(design_phases_rad: Sequence[float]) -> tuple[int, int]:
    """The first port pair whose design fringe phases differ closest to 90 degrees."""
    phases = np.asarray(design_phases_rad, dtype=float)
    pairs = list(itertools.combinations(range(phases.size), 2))
    return min(pairs, key=lambda p: abs(abs(np.sin(phases[p[0]] - phases[p[1]])) - 1.0))


def library_methods() -> list[Method]:
    """The learned calibration and the library's baselines."""
    fsr = DESIGN_FSR_HZ
    return [
        Method(LEARNED, lambda d: wm.Calibrator(fsr)),
        Method(LEARNED_ML, lambda d: wm.Calibrator(fsr, retrieval="ml")),
        Method(CONVENTIONAL, lambda d: wm.ConventionalCalibrator(fsr, d.design_port_phases_rad)),
        Method(EXTENDED, lambda d: ExtendedConventionalCalibrator(fsr)),
        Method(NONLINEAR, lambda d: NonlinearFitCalibrator(fsr)),
        Method(
            "Ellipse (2 ports)",
            lambda d: EllipseCalibrator(fsr, quadrature_pair(d.design_port_phases_rad)),
        ),
        Method(PLANE, lambda d: PlaneEllipseCalibrator(fsr)),
    ]


def hoqi_methods() -> list[Method]:
    """hoqi-bench's methods on the quadrature pair; empty (with a note) when absent."""
    try:
        names = hoqi_method_names()
    except PeerUnavailable as exc:
        print(f"> hoqi-bench skipped: {exc}\n")
        return []
    return [
        Method(
            f"hoqi-bench {name}",
            lambda d, name=name: HoqiCalibrator(
                DESIGN_FSR_HZ, name, quadrature_pair(d.design_port_phases_rad), POWER_W / d.ports
            ),
        )
        for name in names
    ]


# ---------------------------------------------------------------------------- simulation
@dataclass
class MethodResult:
    """Per-device figures of one method in one regime and port count."""

    mean_square_hz2: list[float] = field(default_factory=list)
    max_hz: list[float] = field(default_factory=list)
    over_crlb: list[float] = field(default_factory=list)
    fit_s: list[float] = field(default_factory=list)
    predict_per_s: list[float] = field(default_factory=list)
    convergence: list[float] = field(default_factory=list)
    failed: int = 0

    @property
    def devices(self) -> int:
        """Devices attempted."""
        return len(self.mean_square_hz2) + self.failed

    def rms_hz(self) -> float:
        """RMS error over the test readings of every fitted device (Hz)."""
        return float(np.sqrt(np.mean(self.mean_square_hz2))) if self.mean_square_hz2 else np.nan

    def median_over_crlb(self) -> float:
        """Median over fitted devices of RMS/CRLB."""
        return float(np.median(self.over_crlb)) if self.over_crlb else np.nan


def evaluate(method: Method, trial, result: MethodResult, crlb_hz: float) -> None:
    """Fit one method on a trial's sweep, retrieve its test readings, record the figures."""
    calibrator = method.make(trial.device)
    start = time.perf_counter()
    try:
        calibrator.fit(trial.train_powers, trial.train_hz)
    except FIT_ERRORS:
        result.failed += 1
        return
    result.fit_s.append(time.perf_counter() - start)
    seconds, predicted = median_time_s(
        lambda: calibrator.predict(trial.test_powers), PREDICT_REPEATS
    )
    error = trial.error_hz(predicted)
    rms = float(np.sqrt(np.mean(error**2)))
    result.mean_square_hz2.append(rms**2)
    result.max_hz.append(float(np.max(np.abs(error))))
    result.over_crlb.append(rms / crlb_hz)
    result.predict_per_s.append(error.size / seconds)


def run_regime(
    regime: Regime,
    ports: int,
    methods: Sequence[Method],
    *,
    devices: int,
    seed: int,
    convergence_devices: int = CONVERGENCE_DEVICES,
    starts: int = STARTS,
    test_samples: int = TEST_SAMPLES,
) -> dict[str, MethodResult]:
    """Every method on ``devices`` devices of one regime and port count.

    The nonlinear fit's convergence study (``starts`` random starting points within
    +-``START_SPREAD`` of design) runs on the first ``convergence_devices`` devices.

    Returns
    -------
    dict
        Method name to its :class:`MethodResult`.
    """
    results = {method.name: MethodResult() for method in methods}
    for k, trial in enumerate(trials(regime, ports, devices, seed, test_samples)):
        progress(f"{regime.key}: {ports} ports, device {k + 1}/{devices}")
        crlb_hz = trial.crlb_rms_hz()
        for method in methods:
            evaluate(method, trial, results[method.name], crlb_hz)
        if NONLINEAR in results and k < convergence_devices:
            study = convergence_share(
                trial.train_powers,
                trial.train_hz,
                fsr_hz=DESIGN_FSR_HZ,
                starts=starts,
                spread=START_SPREAD,
                rng=np.random.default_rng([seed, ports, k]),
            )
            results[NONLINEAR].convergence.append(study.share)
    return results


def _number(value: float, digits: int = 3) -> str:
    return "n/a" if not np.isfinite(value) else f"{value:.{digits}g}"


def regime_table(results_by_ports: dict[int, dict[str, MethodResult]]) -> str:
    """Markdown table of one regime: a row per method and port count."""
    headers = [
        "method",
        "ports",
        "RMS (MHz)",
        "max (MHz)",
        "RMS/CRLB median",
        "RMS/CRLB worst",
        "fit (ms)",
        "predict (Msamples/s)",
        "NL converged starts (%)",
        "failed fits",
    ]
    rows = []
    for ports, results in results_by_ports.items():
        for name, r in results.items():
            fitted = bool(r.mean_square_hz2)
            share = f"{100 * np.mean(r.convergence):.0f}" if r.convergence else ""
            rows.append(
                [
                    name,
                    ports,
                    _number(r.rms_hz() / 1e6, 4),
                    _number(max(r.max_hz) / 1e6 if fitted else np.nan, 4),
                    _number(r.median_over_crlb(), 4),
                    _number(max(r.over_crlb) if fitted else np.nan, 4),
                    _number(1e3 * statistics.median(r.fit_s) if fitted else np.nan),
                    _number(statistics.median(r.predict_per_s) / 1e6 if fitted else np.nan),
                    share,
                    f"{r.failed}/{r.devices}",
                ]
            )
    return markdown_table(headers, rows)


def summary_table(all_results: dict[str, dict[int, dict[str, MethodResult]]], ports: int) -> str:
    """RMS (MHz) of every method (rows) in every regime (columns) for one port count."""
    keys = list(all_results)
    names = list(next(iter(all_results.values()))[ports])
    rows = [
        [name] + [_number(all_results[key][ports][name].rms_hz() / 1e6, 4) for key in keys]
        for name in names
    ]
    return markdown_table(["method \\ RMS (MHz)"] + keys, rows)


# ---------------------------------------------------------------------------- measured data
@dataclass(frozen=True)
class MeasuredRow:
    """One reference-free method on the measured record."""

    name: str
    channels: str
    rms_mrad: float
    time_per_sample_s: float
    note: str = ""


def phase_difference_rms_rad(phase_rad, reference_rad) -> float:
    """RMS of ``s phase - reference - c`` (rad), wrapped, for the sign ``s`` and constant
    ``c`` (the circular mean) that minimise it."""
    best = np.inf
    for sign in (1.0, -1.0):
        difference = np.exp(1j * (sign * np.asarray(phase_rad) - reference_rad))
        residual = np.angle(difference * np.conj(np.mean(difference)))
        best = min(best, float(np.sqrt(np.mean(residual**2))))
    return best


def load_measured(data_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """``DC CH1..3`` (V) and MiniPTI's published ``Interferometric Phase`` (rad)."""
    readings = _csv_columns(data_dir / "Decimation_Comercial.csv", MEASURED_PORTS)
    published = _csv_columns(data_dir / "PTI_Inversion_Comercial.csv", ("Interferometric Phase",))
    return readings, published[:, 0]


def _csv_columns(path: Path, names: Sequence[str]) -> np.ndarray:
    with path.open(encoding="utf-8") as handle:
        header = handle.readline().rstrip("\n").split(",")
    columns = [header.index(name) for name in names]
    return np.loadtxt(path, delimiter=",", skiprows=1, usecols=columns, ndmin=2)


def measured_rows(readings: np.ndarray, published: np.ndarray, data_dir: Path) -> list[MeasuredRow]:
    """Every reference-free method on the record: phase agreement and time per sample.

    Times are medians of several runs of fit and retrieval on the whole record, divided by
    the number of samples; MiniPTI's solver is timed alone, with its published
    characterisation (``settings.csv``).
    """
    count = readings.shape[0]
    rows = []

    def add(name: str, channels: str, run: Callable[[], np.ndarray], note="", repeats=None):
        try:
            seconds, phase = median_time_s(run, repeats or MEASURED_REPEATS)
        except FIT_ERRORS as exc:
            rows.append(MeasuredRow(name, channels, np.nan, np.nan, f"failed: {exc}"))
            return
        rms = phase_difference_rms_rad(phase, published)
        rows.append(MeasuredRow(name, channels, 1e3 * rms, seconds / count, note))

    progress("measured data: plane ellipse and ellipses")
    add(PLANE, "1,2,3", lambda: plane_ellipse_phase(fit_plane_ellipse(readings), readings))
    pairs = list(itertools.combinations(range(3), 2))
    for i, j in pairs:
        x, y = readings[:, i], readings[:, j]
        add(
            "Ellipse (2 ports)",
            f"{i + 1},{j + 1}",
            lambda x=x, y=y: ellipse_phase(fit_ellipse(x, y), x, y),
        )
    try:
        names = hoqi_method_names()
    except PeerUnavailable as exc:
        print(f"> hoqi-bench skipped on the measured data: {exc}\n")
        names = []
    level = float(readings.mean())
    for name in names:
        progress(f"measured data: hoqi-bench {name}")
        for i, j in pairs:
            x, y = readings[:, i], readings[:, j]
            add(
                f"hoqi-bench {name}",
                f"{i + 1},{j + 1}",
                lambda x=x, y=y, name=name: hoqi_fit(name, x, y, mean_intensity=level)["phase_rad"],
                "nominal DC level: record mean" if name == "raw_atan2" else "",
            )
    progress("measured data: MiniPTI solver")
    try:
        solver = minipti_solver(data_dir / "settings.csv")
    except PeerUnavailable as exc:
        print(f"> MiniPTI skipped: {exc}\n")
    else:
        add(
            "MiniPTI per-sample solver",
            "1,2,3",
            lambda: solver(readings),
            "solver only, with MiniPTI's published characterisation (settings.csv)",
            MINIPTI_REPEATS,
        )
    return rows


def measured_table(rows: Sequence[MeasuredRow]) -> str:
    """Markdown table of the measured-data comparison."""
    headers = ["method", "channels", "rms vs published (mrad)", "time per sample (us)", "note"]
    body = [
        [r.name, r.channels, _number(r.rms_mrad, 3), _number(1e6 * r.time_per_sample_s, 3), r.note]
        for r in rows
    ]
    return markdown_table(headers, body)


# ---------------------------------------------------------------------------- targets
def targets_table(all_results, measured: Sequence[MeasuredRow] | None) -> str:
    """The benchmark targets, each with its measured figure and met/missed."""
    rows = []

    def add(target: str, figure: str, met: bool | None) -> None:
        rows.append([target, figure, "n/a" if met is None else ("met" if met else "missed")])

    for key, by_ports in all_results.items():
        for learned, label in ((LEARNED, "learned (paper, pinv)"), (LEARNED_ML, "learned ML")):
            parts, ok = [], True
            for ports, results in by_ports.items():
                complete = {n: r for n, r in results.items() if r.failed == 0 and r.mean_square_hz2}
                best = min(complete, key=lambda n: complete[n].rms_hz())
                ratio = results[learned].rms_hz() / complete[best].rms_hz()
                ok &= ratio <= 1.05
                parts.append(f"{ports}p: {ratio:.3f}x best ({best})")
            add(f"{key}: {label} RMS lowest or within 5 % of the lowest", "; ".join(parts), ok)

    def per_ports(key, figure: Callable[[dict[str, MethodResult]], float]) -> dict[int, float]:
        return {p: figure(r) for p, r in all_results[key].items()} if key in all_results else {}

    improvement = per_ports("table1", lambda r: r[CONVENTIONAL].rms_hz() / r[LEARNED].rms_hz())
    if improvement:
        add(
            "table1: learned RMS >= 50x better than conventional",
            "; ".join(f"{p}p: {v:.1f}x" for p, v in improvement.items()),
            all(v >= 50 for v in improvement.values()),
        )
    speedup = per_ports(
        "table1",
        lambda r: statistics.median(r[NONLINEAR].fit_s) / statistics.median(r[LEARNED].fit_s),
    )
    if speedup:
        add(
            "table1: learned fit >= 20x faster than nonlinear fit (median fit times)",
            "; ".join(f"{p}p: {v:.2f}x" for p, v in speedup.items()),
            all(v >= 20 for v in speedup.values()),
        )
    for key in ("power05", "fluct30"):
        if key not in all_results or "table1" not in all_results:
            continue
        parts, ok = [], True
        for ports in all_results[key]:
            drift = {
                name: all_results[key][ports][name].median_over_crlb()
                / all_results["table1"][ports][name].median_over_crlb()
                for name in (LEARNED, EXTENDED)
            }
            ok &= abs(drift[LEARNED] - 1) <= 0.10 and drift[EXTENDED] > 1.10
            parts.append(
                f"{ports}p: learned {drift[LEARNED]:.3f}x, extended {drift[EXTENDED]:.3g}x"
            )
        add(
            f"{key}: learned RMS/CRLB within 10 % of table1, extended conventional > 10 % worse",
            "; ".join(parts),
            ok,
        )
    if measured:
        by_name = {r.name: r for r in measured}
        plane = by_name[PLANE]
        add(
            "measured: plane ellipse within 10 mrad rms of MiniPTI's published phase",
            f"{plane.rms_mrad:.2f} mrad",
            plane.rms_mrad <= 10,
        )
        solver = by_name.get("MiniPTI per-sample solver")
        if solver is None:
            add(
                "measured: plane ellipse >= 100x faster per sample than MiniPTI's solver",
                "MiniPTI absent",
                None,
            )
        else:
            factor = solver.time_per_sample_s / plane.time_per_sample_s
            add(
                "measured: plane ellipse >= 100x faster per sample than MiniPTI's solver",
                f"{factor:.0f}x ({1e6 * plane.time_per_sample_s:.3g} vs "
                f"{1e6 * solver.time_per_sample_s:.3g} us)",
                factor >= 100,
            )
    return markdown_table(["target", "measured", "status"], rows)


# ---------------------------------------------------------------------------- main
def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--devices", type=int, default=None, help="devices per regime and ports")
    parser.add_argument("--quick", action="store_true", help="smoke run with few devices")
    parser.add_argument("--seed", type=int, default=0, help="seed of devices and data")
    args = parser.parse_args(argv)
    devices = args.devices or (QUICK_DEVICES if args.quick else DEFAULT_DEVICES)
    if devices < 1:
        parser.error("--devices must be >= 1")
    convergence_devices = 1 if args.quick else CONVERGENCE_DEVICES
    started = time.perf_counter()
    warnings.simplefilter("ignore", NonlinearFitWarning)

    print("# Peers benchmark\n")
    print(
        f"Peers: hoqi-bench {peer_version('hoqi-bench')}, minipti {peer_version('minipti')}; "
        f"numpy {np.__version__}, wavemeter {wm.__version__}.\n"
    )
    methods = library_methods() + hoqi_methods()
    print(
        f"Simulation: {devices} devices per regime and port count (seed {args.seed}); "
        f"source {POWER_W * 1e3:g} mW, noise {NOISE_W * 1e3:g} mW; "
        f"{TEST_SAMPLES} test readings at random frequencies in the calibrated span; "
        f"RMS pools the test readings of every fitted device, max and worst are over devices, "
        f"fit time and throughput are medians over devices (predict: median of "
        f"{PREDICT_REPEATS} runs each). Nonlinear-fit convergence: {STARTS} random starts "
        f"within +-{START_SPREAD:.0%} of design on the first "
        f"{min(convergence_devices, devices)} device(s) of each regime and port count (a "
        f"start is right when it converges within 1 % of the best cost). Two-channel methods "
        f"use the design port pair closest to quadrature. A failed fit (an exception: no "
        f"FSR locks inside the +-20 % bracket, a hoqi-bench failure code) is counted and its "
        f"device left out of that method's error figures.\n"
    )
    all_results = {}
    for regime in REGIMES:
        all_results[regime.key] = {
            ports: run_regime(
                regime,
                ports,
                methods,
                devices=devices,
                seed=args.seed,
                convergence_devices=convergence_devices,
            )
            for ports in PORTS
        }
        print(f"## {regime.key}: {regime.title}\n")
        print(regime_table(all_results[regime.key]) + "\n")
    for ports in PORTS:
        print(f"## Summary, {ports} ports: RMS (MHz) per regime\n")
        print(summary_table(all_results, ports) + "\n")

    measured = None
    print("## Measured data: MiniPTI 3x3 fiber coupler, reference-free phase\n")
    if (DATA_DIR / "Decimation_Comercial.csv").exists():
        readings, published = load_measured(DATA_DIR)
        measured = measured_rows(readings, published, DATA_DIR)
        print(
            f"{readings.shape[0]} samples of {', '.join(MEASURED_PORTS)} (V); rms difference "
            "from MiniPTI's published `Interferometric Phase` after removing a constant "
            "offset and choosing the sign; time per sample = median of several runs of fit + "
            "retrieval on the whole record / samples, measured side by side in this run.\n"
        )
        print(measured_table(measured) + "\n")
    else:
        print(f"> {DATA_DIR} not found: measured-data table skipped.\n")

    print("## Targets\n")
    print(targets_table(all_results, measured) + "\n")
    elapsed = time.perf_counter() - started
    progress(f"done in {elapsed:.0f} s\n")
    print(f"Run time: {elapsed:.0f} s.")


if __name__ == "__main__":
    main()

"""The main job: simulate a Table 1 3x3 device, calibrate, measure and compare with the CRLB."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..analysis.metrics import error_summary_hz, frequency_error_hz
from ..atomic import atomic_path
from ..calibration.baselines import ConventionalCalibrator
from ..calibration.learned import Calibrator
from ..io._reader import write_table
from ..model.cone import delay_phase_rad
from ..model.limits import crlb_frequency_std
from ..simulation.interferometer import Interferometer

__all__ = ["run_demo", "DEMO_SETUP"]

DEMO_SETUP = {
    "ports": 3,
    "design_fsr_hz": 50e9,
    "training_samples": 2001,
    "test_samples": 20000,
    "power_w": 1e-3,
    "noise_w": 5e-7,
}


def _port_columns(powers_w: np.ndarray) -> dict[str, np.ndarray]:
    return {f"p{k + 1}_w": powers_w[:, k] for k in range(powers_w.shape[1])}


def run_demo(out_dir, seed: int = 1, quiet: bool = False) -> dict:
    """Run the demo and write ``sweep.csv``, ``test.csv``, calibrations and ``results.json``.

    Parameters
    ----------
    out_dir : str or Path
        Output folder (created if missing).
    seed : int
        Seed of the simulated device and its noise.
    quiet : bool
        Print nothing.

    Returns
    -------
    dict
        The summary written to ``results.json`` (errors in Hz).
    """
    setup = DEMO_SETUP
    rng = np.random.default_rng(seed)
    device = Interferometer.table1(setup["ports"], seed=seed, fsr_hz=setup["design_fsr_hz"])
    sweep_hz = device.sweep_hz(setup["training_samples"])
    sweep_w = device.powers(sweep_hz, setup["power_w"], setup["noise_w"], rng)
    half = device.true_fsr_hz / 2
    test_hz = device.center_hz + rng.uniform(-half, half, setup["test_samples"])
    test_w = device.powers(test_hz, setup["power_w"], setup["noise_w"], rng)

    learned = Calibrator(fsr_hz=setup["design_fsr_hz"]).fit(sweep_w, sweep_hz)
    conventional = ConventionalCalibrator(
        fsr_hz=setup["design_fsr_hz"], port_phases_rad=device.design_port_phases_rad
    ).fit(sweep_w, sweep_hz)
    true_phase = delay_phase_rad(test_hz, device.center_hz, device.delay_s)
    bound_hz = crlb_frequency_std(
        device.true_map(), true_phase, setup["power_w"], setup["noise_w"], device.true_fsr_hz
    )
    crlb_rms_hz = float(np.sqrt(np.mean(bound_hz**2)))
    predictions = {
        name: cal.predict(test_w)
        for name, cal in (("learned", learned), ("conventional", conventional))
    }
    summary = {
        "setup": {**setup, "seed": seed, "true_fsr_hz": device.true_fsr_hz},
        "crlb_rms_hz": crlb_rms_hz,
        "fitted_fsr_hz": learned.fsr_hz_,
        "methods": {
            name: error_summary_hz(frequency_error_hz(predicted, test_hz, device.true_fsr_hz))
            for name, predicted in predictions.items()
        },
    }

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_table(out / "sweep.csv", {"frequency_hz": sweep_hz, **_port_columns(sweep_w)})
    write_table(
        out / "results.csv",
        {
            "true_frequency_hz": test_hz,
            "learned_frequency_hz": predictions["learned"],
            "conventional_frequency_hz": predictions["conventional"],
            "crlb_std_hz": bound_hz,
            **_port_columns(test_w),
        },
    )
    learned.save(out / "learned.wmcal.json")
    conventional.save(out / "conventional.wmcal.json")
    with atomic_path(out / "results.json") as temporary:
        temporary.write_text(json.dumps(summary, indent=1) + "\n", encoding="utf-8")
    if not quiet:
        _print_summary(summary, out)
    return summary


def _print_summary(summary: dict, out: Path) -> None:
    from rich.console import Console
    from rich.table import Table

    setup = summary["setup"]
    console = Console()
    console.print(
        f"Table 1 {setup['ports']}x{setup['ports']} device (seed {setup['seed']}): true FSR "
        f"{setup['true_fsr_hz'] / 1e9:.4f} GHz, fitted {summary['fitted_fsr_hz'] / 1e9:.4f} GHz; "
        f"{setup['training_samples']} calibration and {setup['test_samples']} test samples at "
        f"{setup['power_w'] * 1e3:g} mW, noise {setup['noise_w'] * 1e3:g} mW"
    )
    table = Table(title="Frequency error on the test set")
    for header in ("method", "RMS (MHz)", "max (MHz)", "p99 (MHz)", "RMS / CRLB"):
        table.add_column(header, justify="right")
    crlb = summary["crlb_rms_hz"]
    for name, stats in summary["methods"].items():
        table.add_row(
            name,
            f"{stats['rms_hz'] / 1e6:.3f}",
            f"{stats['max_hz'] / 1e6:.3f}",
            f"{stats['p99_hz'] / 1e6:.3f}",
            f"{stats['rms_hz'] / crlb:.3f}",
        )
    table.add_row("CRLB", f"{crlb / 1e6:.3f}", "", "", "1.000")
    console.print(table)
    console.print(f"wrote sweep.csv, results.csv, *.wmcal.json and results.json to {out}/")

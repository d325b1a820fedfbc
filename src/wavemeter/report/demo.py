"""The main job: simulate a Table 1 3x3 device, calibrate, measure and compare with the CRLB."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..atomic import atomic_path, check_output
from ..calibration.files.registry import calibrator_class
from ..exceptions import InputError
from ..io import write_table
from ..model.cone import delay_phase_rad
from ..model.errors import error_summary_hz, frequency_error_hz
from ..model.limits import crlb_frequency_std
from ..simulation.interferometer import Interferometer

__all__ = ["run_demo", "print_demo_summary", "prepare_demo_folder", "DEMO_SETUP", "DEMO_FILES"]

DEMO_SETUP = {
    "ports": 3,
    "design_fsr_hz": 50e9,
    "training_samples": 2001,
    "test_samples": 20000,
    "power_w": 1e-3,
    "noise_w": 5e-7,
}


#: the files the demo writes in its folder; a later run replaces these and nothing else
DEMO_FILES = (
    "sweep.csv",
    "results.csv",
    "learned.wmcal.json",
    "conventional.wmcal.json",
    "results.json",
)


def prepare_demo_folder(out_dir) -> Path:
    """Create the demo folder if missing and check that the demo may write its files there.

    Files of an earlier demo (:data:`DEMO_FILES`) are replaced; nothing else in the folder
    is touched.

    Raises
    ------
    InputError
        When ``out_dir`` exists and is not a folder, or one of the demo's file names in it
        is not a regular file (a folder, a device, a pipe).
    """
    out = Path(out_dir)
    if not str(out_dir):
        raise InputError("the demo folder name is empty: give a folder name")
    if out.exists() and not out.is_dir():
        raise InputError(f"cannot use {out} as the demo folder: it exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    for name in DEMO_FILES:
        check_output(out / name, force=True)
    return out


def _port_columns(powers_w: np.ndarray) -> dict[str, np.ndarray]:
    return {f"p{k + 1}_w": powers_w[:, k] for k in range(powers_w.shape[1])}


def run_demo(out_dir, seed: int = 1) -> dict:
    """Run the demo and write :data:`DEMO_FILES`: the sweep, the test results, both
    calibrations and a summary.

    Parameters
    ----------
    out_dir : str or Path
        Output folder (created if missing); the files of an earlier demo there are
        replaced, nothing else is touched.
    seed : int
        Seed of the simulated device and its noise.

    Returns
    -------
    dict
        The summary written to ``results.json`` (errors in Hz).
    """
    out = prepare_demo_folder(out_dir)  # before any work
    setup = DEMO_SETUP
    rng = np.random.default_rng(seed)
    device = Interferometer.table1(setup["ports"], seed=seed, fsr_hz=setup["design_fsr_hz"])
    sweep_hz = device.sweep_hz(setup["training_samples"])
    sweep_w = device.powers(sweep_hz, setup["power_w"], setup["noise_w"], rng)
    half = device.true_fsr_hz / 2
    test_hz = device.center_hz + rng.uniform(-half, half, setup["test_samples"])
    test_w = device.powers(test_hz, setup["power_w"], setup["noise_w"], rng)

    learned = calibrator_class("learned")(fsr_hz=setup["design_fsr_hz"]).fit(sweep_w, sweep_hz)
    conventional = calibrator_class("conventional")(
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
    return summary


def print_demo_summary(summary: dict) -> None:
    """Print the device, and the errors of both methods against the CRLB, on stdout."""
    from rich.console import Console
    from rich.table import Table

    setup = summary["setup"]
    console = Console()
    console.print(
        f"Table 1 {setup['ports']}x{setup['ports']} device (seed {setup['seed']}): true FSR "
        f"{setup['true_fsr_hz'] / 1e9:.6f} GHz, fitted {summary['fitted_fsr_hz'] / 1e9:.6f} GHz; "
        f"{setup['training_samples']} calibration and {setup['test_samples']} test samples at "
        f"{setup['power_w']:.4g} W, noise {setup['noise_w']:.4g} W"
    )
    table = Table(title="Frequency error on the test set")
    for header in ("method", "RMS (MHz)", "max (MHz)", "p99 (MHz)", "RMS/CRLB"):
        table.add_column(header, justify="right")
    crlb = summary["crlb_rms_hz"]
    for name, stats in summary["methods"].items():
        table.add_row(
            name,
            f"{stats['rms_hz'] / 1e6:.4f}",
            f"{stats['max_hz'] / 1e6:.4f}",
            f"{stats['p99_hz'] / 1e6:.4f}",
            f"{stats['rms_hz'] / crlb:.3f}",
        )
    table.add_row("CRLB", f"{crlb / 1e6:.4f}", "", "", "1.000")
    console.print(table)

"""`wavemeter evaluate`: frequency errors on readings of known frequency."""

from __future__ import annotations

import json
from pathlib import Path

import click
import numpy as np

from ..exceptions import InputError
from ._common import (
    PORT_PHASES,
    QUIET,
    about,
    check_ports,
    column_options,
    column_request,
    load,
    method_label,
    port_phases_rad,
    read,
)


def _noise_std_w(calibration) -> float:
    """Detector noise (W) of a learned calibration's residual (mean over a set's windows)."""
    if "coarse_hz" in calibration.requires:
        return float(np.mean([window.noise_std_w_ for window in calibration.windows_]))
    return calibration.noise_std_w_


def _other_method(calibration, sweep, options, phases):
    """The other method (learned <-> conventional) fitted on the sweep file."""
    from ..report.html import comparison_calibration

    request = column_request(options)
    table = read(
        sweep, request, need_x=True, drop_invalid=options["drop_invalid"], quiet=options["quiet"]
    ).valid_only()
    check_ports(calibration, "the calibration", table, request.ports is not None)
    with about(sweep):
        return comparison_calibration(
            calibration, table.powers_w, table.x_hz, table.monitor_w, phases
        )


def _evaluation(calibrations: dict, table) -> dict:
    """Error summaries (Hz) of each calibration on a table with known frequencies, and the
    Cramer-Rao bound of the first learned one."""
    from ..analysis.metrics import error_summary_hz, frequency_error_hz
    from ..report.html import crlb_per_reading_hz

    truth = table.x_hz
    coarse = table.coarse_hz if table.coarse_hz is not None else truth
    results, bound, noise = {}, None, None
    for label, calibration in calibrations.items():
        extra = {"coarse_hz": coarse} if "coarse_hz" in calibration.requires else {}
        predicted = calibration.predict(table.powers_w, **extra)
        error = frequency_error_hz(predicted, truth, calibration.fsr_hz_)
        results[label] = error_summary_hz(error)
        if bound is None:
            bound = crlb_per_reading_hz(calibration, table.powers_w, truth)
            noise = None if bound is None else _noise_std_w(calibration)
    summary = {"methods": results, "crlb_rms_hz": None, "noise_std_w": noise}
    if bound is not None:
        crlb_rms = float(np.sqrt(np.mean(bound**2)))
        summary["crlb_rms_hz"] = crlb_rms
        for stats in results.values():
            stats["rms_over_crlb"] = stats["rms_hz"] / crlb_rms
    return summary


def _print_evaluation(report: dict) -> None:
    click.echo(
        f"{report['test_file']}: {report['samples']} readings, truth {report['truth_column']} "
        f"({report['truth_unit']})"
    )
    width = max(len(label) for label in report["methods"]) + 2
    header = ("RMS MHz", "max MHz", "p95 MHz", "p99 MHz", "RMS/CRLB")
    click.echo(f"{'method':<{width}}" + "".join(f"{h:>12}" for h in header))
    for label, stats in report["methods"].items():
        ratio = stats.get("rms_over_crlb")
        cells = [stats[key] / 1e6 for key in ("rms_hz", "max_hz", "p95_hz", "p99_hz")]
        click.echo(
            f"{label:<{width}}"
            + "".join(f"{value:>12.4f}" for value in cells)
            + (f"{ratio:>12.3f}" if ratio is not None else f"{'-':>12}")
        )
    if report["crlb_rms_hz"] is not None:
        click.echo(
            f"CRLB {report['crlb_rms_hz'] / 1e6:.4f} MHz RMS (noise {report['noise_std_w']:.3g} "
            "from the calibration residual, learned map as the true one)"
        )
    if "adjacent" in report:
        adjacent = report["adjacent"]
        click.echo(
            f"adjacent FSR ({adjacent['windows_evaluated']} windows): "
            + ", ".join(
                f"{name} RMS {adjacent[name]['rms_hz'] / 1e6:.4f} MHz"
                for name in ("own", "adjacent", "conventional_own", "conventional_adjacent")
            )
        )


@click.command()
@click.argument("calibration_file", metavar="CAL", type=click.Path(dir_okay=False))
@click.argument("test", type=click.Path(dir_okay=False))
@click.option(
    "--sweep",
    type=click.Path(dir_okay=False),
    help="Sweep to fit the other method (learned <-> conventional) for comparison.",
)
@click.option(
    "--compare",
    "compare_files",
    multiple=True,
    type=click.Path(dir_okay=False),
    help="Another calibration file to evaluate side by side (repeatable).",
)
@PORT_PHASES
@click.option(
    "--coarse",
    "coarse_column",
    metavar="COL",
    help="Coarse frequency column for a calibration set (default: the truth).",
)
@click.option(
    "--adjacent",
    is_flag=True,
    help="Also apply each FSR window's map to the neighbouring FSRs (paper Fig. 9).",
)
@click.option("--json", "as_json", is_flag=True, help="Print the results as JSON.")
@column_options()
@QUIET
def evaluate(
    calibration_file,
    test,
    sweep,
    compare_files,
    port_phases_deg,
    coarse_column,
    adjacent,
    as_json,
    **options,
):
    """Frequency errors on a test file with known frequencies, against the CRLB.

    Reports RMS, max, 95th and 99th percentile |error| (MHz) of CAL, of each --compare
    calibration and, with --sweep, of the other method fitted on that sweep; errors are
    taken modulo the FSR. RMS/CRLB divides by the Cramer-Rao bound of the learned map
    with the noise estimated from its calibration residual (a residual holding
    unmodelled structure makes that bound loose). A calibration set picks each reading's
    window from --coarse, else from the truth.

    \b
    Example:
      wavemeter evaluate chip.wmcal.json sweep-test.csv --sweep sweep.csv
      wavemeter evaluate set.wmcal.json test.csv --adjacent --json
    """
    calibration = load(calibration_file)
    request = column_request(options, coarse=coarse_column)
    table = read(
        test,
        request,
        need_x=True,
        drop_invalid=options["drop_invalid"],
        quiet=options["quiet"] or as_json,
    ).valid_only()
    explicit = request.ports is not None
    check_ports(calibration, calibration_file, table, explicit)
    calibrations = {method_label(calibration): calibration}
    for path in compare_files:
        other = load(path)
        check_ports(other, path, table, explicit)
        calibrations.setdefault(f"{method_label(other)} ({Path(path).name})", other)
    if sweep is not None:
        other = _other_method(calibration, sweep, options, port_phases_rad(port_phases_deg))
        calibrations[f"{method_label(other)} (fitted on {Path(sweep).name})"] = other
    report = {
        "calibration_file": str(calibration_file),
        "test_file": str(test),
        "samples": table.n_rows,
        "dropped_rows": table.dropped_rows,
        "truth_column": table.x_column,
        "truth_unit": table.x_unit,
    }
    with about(test):
        report.update(_evaluation(calibrations, table))
    if adjacent:
        if "coarse_hz" not in calibration.requires:
            raise InputError(
                f"--adjacent needs a per-FSR calibration set; {calibration_file} is a single "
                "calibration: calibrate with --per-fsr on a sweep over several FSRs"
            )
        with about(test):
            from ..analysis.evaluation import adjacent_evaluation
            from ..calibration.baselines import ConventionalCalibrator

            phases = port_phases_rad(port_phases_deg)
            if phases is None:
                phases = calibration.windows_[0].get_params().get("port_phases_rad")
            baseline = ConventionalCalibrator(port_phases_rad=phases)
            report["adjacent"] = adjacent_evaluation(
                calibration, table.powers_w, table.x_hz, baseline
            )
    if as_json:
        click.echo(json.dumps(report, indent=1))
    elif not options["quiet"]:
        _print_evaluation(report)


command = evaluate

"""`wavemeter evaluate`: frequency errors on readings of known frequency.

Each calibration's own checks on the test readings (``evaluation_checks``: a cascade's
wrong fringe orders against those it predicts and flags; with ``--adjacent``, a set's maps
on the neighbouring FSRs) are printed beside the errors.
"""

from __future__ import annotations

import json
from pathlib import Path

import click

from ..calibration.contract.flags import flag_summary
from ..exceptions import InputError
from ..jobs.readings import check_reading_options
from ._common import (
    PORT_PHASES,
    QUIET,
    about,
    check_ports,
    column_options,
    column_request,
    load,
    noise_text,
    note,
    port_phases_rad,
    read,
    say,
)
from ._temperature import missing_temperature, needs_temperature


def _other_method(calibration, sweep, options, phases):
    """The other method fitted on the sweep file (learned <-> conventional; a wide band:
    the learned calibration set per FSR)."""
    from ..report.content import comparison_calibration

    request = column_request(options)
    table = read(
        sweep, request, need_x=True, drop_invalid=options["drop_invalid"], quiet=options["quiet"]
    ).valid_only()
    check_ports(calibration, "the calibration", table, request.ports is not None)
    with about(sweep):
        return comparison_calibration(
            calibration, table.powers_w, table.x_hz, table.monitor_w, phases
        )


#: a single-FSR calibration whose span exceeds its FSR by more than this is an aliased fit
#: or was fitted over several FSRs (a one-FSR sweep stops one step short of the FSR)
SPAN_OVER_FSR_LIMIT = 1.05
ERROR_HEADER = ("RMS MHz", "max MHz", "p95 MHz", "p99 MHz", "RMS/CRLB")
FSR_HEADER = ("RMS mod FSR MHz", "RMS/CRLB", "FSR GHz", "truth outside span", "gross error")


def _percent(fraction: float) -> str:
    return f"{100 * fraction:.3g} %"


def _ratio(value) -> str:
    return "-" if value is None else f"{value:.3f}"


def _table(labels, header, rows) -> list[str]:
    """Lines of a table: a method column, then right-aligned cells under ``header``."""
    width = max(len(label) for label in labels) + 2
    widths = [max(12, len(title) + 2) for title in header]

    def line(first: str, cells) -> str:
        return f"{first:<{width}}" + "".join(
            f"{cell:>{cell_width}}" for cell, cell_width in zip(cells, widths, strict=True)
        )

    return [line("method", header)] + [
        line(label, cells) for label, cells in zip(labels, rows, strict=True)
    ]


def _coarse_users(calibrations: dict) -> str:
    """The calibrations that need a coarse frequency, for the messages
    (``learned per FSR calibrations``, ``wideband calibrations``)."""
    kinds = [
        f"{calibration.method_label} calibrations"
        for calibration in calibrations.values()
        if "coarse_hz" in calibration.requires
    ]
    return ", ".join(dict.fromkeys(kinds))


def _check_lines(checks: dict) -> list[str]:
    """One line per check a calibration made of itself (its wrong fringe orders, ...)."""
    return [
        f"{check.title} of {label}: {check.text}"
        for label, found in checks.items()
        for check in found
        if check.name != "adjacent"
    ]


def _print_evaluation(report: dict, calibrations: dict, checks: dict) -> None:
    say(
        False,
        f"{report['test_file']}: {report['samples']} readings, truth {report['truth_column']} "
        f"({report['truth_unit']})",
    )
    methods = report["methods"]
    labels = list(methods)
    say(False, "absolute error (retrieved minus true frequency):")
    rows = [
        [
            f"{stats[key] / 1e6:.4f}"
            for key in ("rms_abs_hz", "max_abs_hz", "p95_abs_hz", "p99_abs_hz")
        ]
        + [_ratio(stats.get("rms_abs_over_crlb"))]
        for stats in methods.values()
    ]
    say(False, "\n".join(_table(labels, ERROR_HEADER, rows)))
    say(False, "error modulo each calibration's FSR, and readings it cannot place:")
    rows = [
        [
            f"{stats['rms_mod_fsr_hz'] / 1e6:.4f}",
            _ratio(stats.get("rms_mod_fsr_over_crlb")),
            f"{stats['fsr_hz'] / 1e9:.6f}",
            _percent(stats["outside_span_fraction"]),
            _percent(stats["gross_error_fraction"]),
        ]
        for stats in methods.values()
    ]
    say(False, "\n".join(_table(labels, FSR_HEADER, rows)))
    if report["crlb_rms_hz"] is not None:
        say(
            False,
            f"CRLB {report['crlb_rms_hz'] / 1e6:.4f} MHz RMS (noise "
            f"{noise_text(report['noise_std_w'])} "
            f"from the calibration residual of {report['crlb_method']}, its map taken as the "
            "true one)",
        )
    for label, stats in methods.items():
        if stats["flagged_readings"]:
            flagged = flag_summary(stats["flagged"], stats["flagged_readings"], report["samples"])
            say(False, f"{label}: {flagged}")
    for line in _check_lines(checks):
        say(False, line)
    users = _coarse_users(calibrations)
    if report["coarse_from"] == "coarse_hz":
        say(False, f"coarse frequency of each reading ({users}): column {report['coarse_column']}")
    elif report["coarse_from"] == "truth":
        say(
            False,
            f"coarse frequency of each reading ({users}): the true frequency, as no --coarse "
            "column was given (in use the coarse values may be worse)",
        )


def _placement_notes(report: dict, calibrations: dict) -> list[str]:
    """One line per method with readings outside its span or off by half an FSR or more."""
    lines = []
    samples = report["samples"]
    for label, stats in report["methods"].items():
        outside = round(stats["outside_span_fraction"] * samples)
        gross = round(stats["gross_error_fraction"] * samples)
        if not (outside or gross):
            continue
        low, high = stats["span_hz"]
        fsr = stats["fsr_hz"]
        parts = []
        if outside:
            parts.append(
                f"{_percent(stats['outside_span_fraction'])} of readings ({outside} of {samples}) "
                f"lie outside the calibrated span {low / 1e12:.3f}..{high / 1e12:.3f} THz"
            )
        if gross:
            parts.append(
                f"{_percent(stats['gross_error_fraction'])}{'' if outside else ' of readings'} "
                f"({gross} of {samples}) are off by more than half the FSR "
                f"({fsr / 1e9:.6f} GHz)"
            )
        calibration = calibrations[label]
        needs_coarse = "coarse_hz" in calibration.requires
        divided = calibration.parts()
        if calibration.absolute_frequency:
            reason = (
                f"a {calibration.method_label} calibration picks each reading's fringe order "
                "itself and reads only the band it was calibrated on: readings outside it, or "
                "noisier than it allows, come back whole FSRs off (measure writes each "
                "reading's flags, ORDER_AMBIGUOUS where the order is in doubt)"
            )
        elif needs_coarse and report["coarse_from"] == "truth":
            reason = "its maps misread them even with the true frequency as the coarse value"
        elif needs_coarse:
            picks = f"{divided[0].kind} and alias" if divided else "fringe order"
            reason = (
                f"a {calibration.method_label} calibration picks each reading's {picks} by "
                "its coarse frequency, which must lie within half an FSR of the truth"
            )
        elif high - low > SPAN_OVER_FSR_LIMIT * fsr:
            reason = (
                f"its FSR is {(high - low) / fsr:,.0f} times shorter than the span it was "
                "calibrated on, so it reads that span modulo a fraction of it (an aliased "
                "fit, or a sweep over several FSRs): recalibrate with the device's FSR "
                "(--fsr), per FSR (--per-fsr) for a sweep over several"
            )
        elif outside:
            reason = (
                "a single-FSR calibration reads frequency modulo its FSR; calibrate over the "
                "band (--per-fsr) and pass coarse frequencies (--coarse)"
            )
        elif high - low > fsr:
            reason = (
                f"its FSR is shorter than the span it was calibrated on "
                f"({(high - low) / 1e9:.6f} GHz), so readings near the ends of the span come "
                "back one FSR off"
            )
        else:
            reason = "its errors there exceed half an FSR: it does not describe these readings"
        lines.append(f"{label}: {' and '.join(parts)}: {reason}")
    return lines


def _print_adjacent(adjacent: dict) -> None:
    say(
        False,
        f"adjacent FSR, {adjacent['windows_evaluated']} windows: each window's map on its own "
        "FSR and on the neighbouring ones (the conventional method fitted per window on this "
        "file)",
    )
    header = ("own FSR RMS MHz", "adjacent FSR RMS MHz", "adjacent/own")
    labels = [adjacent["method"], "conventional"]
    rows = [
        [
            f"{adjacent[prefix + 'own']['rms_hz'] / 1e6:.4f}",
            f"{adjacent[prefix + 'adjacent']['rms_hz'] / 1e6:.4f}",
            f"{adjacent[ratio]:.3f}",
        ]
        for prefix, ratio in (
            ("", "degradation_rms"),
            ("conventional_", "conventional_degradation_rms"),
        )
    ]
    say(False, "\n".join(_table(labels, header, rows)))


def _checks(calibration, table, adjacent: bool) -> list:
    """The checks a calibration makes of itself on the test readings; its adjacent-window
    evaluation only when asked for (it fits the conventional method per window)."""
    return [
        check
        for check in calibration.evaluation_checks(table.powers_w, table.x_hz)
        if adjacent or check.name != "adjacent"
    ]


def _test_temperature_k(calibrations: dict, table):
    """The test readings' chip temperature (K) when a calibration needs it, else None."""
    thermal = [label for label, cal in calibrations.items() if needs_temperature(cal)]
    if not thermal:
        return None
    if table.temperature_k is None:
        raise missing_temperature(
            f"the {thermal[0]} calibration",
            table.source,
            "give the test file a temperature column (found by name with its unit, or "
            "named with --temperature COL)",
        )
    return table.temperature_k


@click.command()
@click.argument("calibration_file", metavar="CAL", type=click.Path(dir_okay=False))
@click.argument("test", type=click.Path(dir_okay=False))
@click.option(
    "--sweep",
    type=click.Path(dir_okay=False),
    help="Sweep to fit the other method (learned <-> conventional; wideband -> learned per "
    "FSR) for comparison; a cascade has none.",
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
    help="Coarse frequency column for a calibration set or a wide-band calibration "
    "(default: the truth).",
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

    Errors are the retrieved minus the true frequency (absolute): a single-FSR calibration
    reads frequency modulo its FSR, so a reading outside its calibrated span is wrong by
    whole FSRs and counts as such. Reports RMS, max, 95th and 99th percentile |error|
    (MHz) of CAL, of each --compare calibration and, with --sweep, of the other method
    fitted on that sweep; then the RMS modulo each calibration's FSR (the precision within
    one FSR), the share of readings outside the calibrated span and the share off by more
    than half an FSR. RMS/CRLB divides by the Cramer-Rao bound of the first learned map
    with the noise estimated from its calibration residual (a residual holding unmodelled
    structure makes that bound loose). A calibration set picks each reading's window, a
    wide-band calibration its fringe order, from --coarse, else from the truth; a thermal
    calibration reads each reading's chip temperature from the test file's temperature
    column (--temperature COL). A cascade calibration needs no coarse frequency (and
    refuses --coarse); its wrong fringe orders are counted against those its
    order_error_probability predicts and those it flags ORDER_AMBIGUOUS.

    \b
    Example:
      wavemeter evaluate chip.wmcal.json sweep-test.csv --sweep sweep.csv
      wavemeter evaluate set.wmcal.json test.csv --adjacent --json
    """
    calibration = load(calibration_file)
    if sweep is not None:
        try:
            calibration.comparison()
        except InputError as exc:
            raise InputError(
                f"--sweep fits another method on the sweep to compare with, and "
                f"{calibration_file} names none ({exc}): leave --sweep out, or pass another "
                "calibration file with --compare"
            ) from exc
    if coarse_column is not None and not compare_files:
        check_reading_options(calibration, name=str(calibration_file), coarse_column=coarse_column)
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
    calibrations = {calibration.method_label: calibration}
    for path in compare_files:
        other = load(path)
        check_ports(other, path, table, explicit)
        calibrations.setdefault(f"{other.method_label} ({Path(path).name})", other)
    if coarse_column is not None and not any(
        "coarse_hz" in each.requires for each in calibrations.values()
    ):
        raise InputError(
            "coarse names a coarse-frequency column, and none of the calibrations evaluated "
            "uses one (a set of windows or a wide band does): leave coarse out",
            parameter="coarse",
        )
    if sweep is not None:
        other = _other_method(calibration, sweep, options, port_phases_rad(port_phases_deg))
        calibrations[f"{other.method_label} (fitted on {Path(sweep).name})"] = other
    report = {
        "calibration_file": str(calibration_file),
        "test_file": str(test),
        "samples": table.n_rows,
        "dropped_rows": table.dropped_rows,
        "truth_column": table.x_column,
        "truth_unit": table.x_unit,
        "coarse_column": table.coarse_column,
    }
    from ..analysis.evaluation import evaluate_calibrations

    with about(test):
        report.update(
            evaluate_calibrations(
                calibrations,
                table.powers_w,
                table.x_hz,
                coarse_hz=table.coarse_hz,
                temperature_k=_test_temperature_k(calibrations, table),
            )
        )
        checks = {
            label: _checks(other, table, adjacent and other is calibration)
            for label, other in calibrations.items()
        }
    if adjacent and not any(check.name == "adjacent" for check in checks[calibration.method_label]):
        raise InputError(
            f"--adjacent needs a per-FSR calibration set (it applies each FSR window's map "
            f"to its neighbours); {calibration_file} is a {calibration.method_label} "
            "calibration (one model): calibrate with --per-fsr on a sweep over several FSRs"
        )
    for label, found in checks.items():
        for check in found:
            if check.name == "adjacent":
                if "unavailable" in check.record:
                    raise InputError(f"{test}: {check.record['unavailable']}")
                report["adjacent"] = check.record
            else:
                report.setdefault(check.name, {})[label] = check.record
    if as_json:
        click.echo(json.dumps(report, indent=1))  # JSON: text escaped by json
    elif not options["quiet"]:
        _print_evaluation(report, calibrations, checks)
        if adjacent:
            _print_adjacent(report["adjacent"])
    for line in _placement_notes(report, calibrations):
        note(options["quiet"], line)


command = evaluate

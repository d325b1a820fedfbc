"""The text lines of a fit report: a label and its words, the settings, the fit's
diagnostics (ports, residual, noise, map) and a re-anchoring's record."""

from __future__ import annotations

from ...units import frequency_text

__all__ = [
    "LABEL_WIDTH",
    "line",
    "settings_text",
    "samples_text",
    "diagnostics_lines",
]

#: width of the label column of the text report
LABEL_WIDTH = 17


def line(label: str, text: str) -> str:
    return f"{label:<{LABEL_WIDTH - 1}} {text}"


def samples_text(samples: int, diagnostics: dict) -> str:
    """The calibration readings, and how many the checks saw when fewer (a long sweep's
    checks run on every k-th reading)."""
    diagnosed = diagnostics.get("diagnostic_samples")
    if isinstance(diagnosed, int) and diagnosed < samples:
        return f"{samples} (checks and diagnostics on {diagnosed}, every k-th reading)"
    return str(samples)


#: how the misfit report's noise estimates read (``diagnostics_["fit"]["noise_method"]``)
_NOISE_SOURCES = {
    "second_difference": "the readings' second differences (model-free)",
    "residual": "the calibration residual",
}


def _setting_text(name: str, value) -> str:
    """One setting as people read it: a frequency in its unit, ``default`` for None, lists
    and nested settings (a set's window) in words, never a Python repr."""
    if value is None:
        return "default"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, dict):
        method = value.get("method")
        inner = value.get("params") if isinstance(value.get("params"), dict) else {}
        listed = ", ".join(f"{key} {_setting_text(key, item)}" for key, item in inner.items())
        return f"{method} ({listed})" if method else listed
    if isinstance(value, (list, tuple)):
        return ", ".join(
            f"({_setting_text(name, item)})"
            if isinstance(item, (list, tuple))
            else _setting_text(name, item)
            for item in value
        )
    if isinstance(value, (int, float)) and name.endswith("_hz"):
        return frequency_text(float(value))
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def settings_text(settings: dict) -> str:
    """``fsr_hz 50 GHz; fsr_tolerance 0.2; retrieval pinv``: library names, values in words."""
    return "; ".join(f"{name} {_setting_text(name, value)}" for name, value in settings.items())


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _number(value) -> str:
    return f"{value:.3g}" if _is_number(value) else "?"


def _per_port(fit: dict, key: str, count: int) -> list:
    values = fit.get(key)
    if isinstance(values, list) and len(values) == count:
        return values
    return [None] * count


def _fit_lines(fit, ports) -> list[str]:
    """Lines for the fit diagnostics (:mod:`wavemeter.calibration.checks.misfit`): each port's
    residual against its model-free noise, the map's conditioning, fitted offsets."""
    if not isinstance(fit, dict) or not fit:
        return []
    names = [port.get("name") if isinstance(port, dict) else "?" for port in ports or []]
    count = len(names)
    residual = _per_port(fit, "residual_rms_w", count)
    ratio = _per_port(fit, "noise_ratio", count)
    lag = _per_port(fit, "lag1_autocorrelation", count)
    lines = [
        line(
            f"fit {name}",
            f"residual {_number(rms)} W, {_number(factor)}x the noise, lag-1 autocorrelation "
            f"{_number(correlation)}",
        )
        for name, rms, factor, correlation in zip(names, residual, ratio, lag, strict=True)
    ]
    method, dof = fit.get("noise_method"), fit.get("noise_dof")
    if isinstance(method, str):
        source = _NOISE_SOURCES.get(method, method.replace("_", " "))
        lines.append(line("noise from", f"{source} ({_number(dof)} degrees of freedom)"))
    if _is_number(fit.get("condition_number")):
        ratio_text = fit.get("pinv_variance_ratio")
        extra = (
            f" (pseudo-inverse phase variance {ratio_text:.3g}x the Cramer-Rao bound's)"
            if _is_number(ratio_text)
            else ""
        )
        lines.append(line("map", f"condition number {fit['condition_number']:.3g}{extra}"))
    offsets = fit.get("offset_w")
    if isinstance(offsets, list) and offsets:
        text = ", ".join(f"{_number(value)} W" for value in offsets)
        lines.append(line("offsets", f"{text} (fitted, subtracted)"))
    return lines


#: the verdicts of a re-anchoring's reference check, the least worrying first
_CHECK_ORDER = ("untested", "ok", "warned", "refused")


def _check_text(check: dict) -> str:
    """A reference check in words: its verdict and the reported line's scatter."""
    verdict = check.get("verdict") if check.get("verdict") in _CHECK_ORDER else "?"
    lines = [line for line in check.get("lines") or [] if isinstance(line, dict)]
    tested = [line for line in lines if _is_number(line.get("p_value"))]
    if verdict == "untested" or not tested:
        return f"{verdict}: no line with two readings"
    line = min(tested, key=lambda item: item["p_value"])
    return (
        f"{verdict}: scatter {_number(line.get('scatter_ratio'))} times the calibration's "
        f"noise ({_number(line.get('observed_scatter_rad'))} rad, expected "
        f"{_number(line.get('expected_scatter_rad'))} rad), p = {_number(check.get('p_value'))} "
        f"over {len(tested)} line(s)"
    )


def _reanchor_lines(record) -> list[str]:
    """Lines for a re-anchoring record: the shift, and how the reference readings scattered
    (the worst window's for a set); tolerant of records read from files."""
    if not isinstance(record, dict):
        return []
    windows = record.get("windows")
    records = [item for item in windows if isinstance(item, dict)] if windows else [record]
    lines_hz = record.get("lines_hz")
    count = len(lines_hz) if isinstance(lines_hz, list) else "?"
    readings = record.get("readings")
    on = f"{count} line(s), {readings if isinstance(readings, int) else '?'} readings"
    if windows:
        text = f"{len(records)} windows on {on}"
    else:
        text = (
            f"phase shift {_number(record.get('phase_shift_rad'))} rad (std "
            f"{_number(record.get('phase_shift_std_rad'))} rad) on {on}"
        )
    lines = [line("re-anchored", text)]
    checks = [item.get("reference_check") for item in records]
    checks = [check for check in checks if isinstance(check, dict)]
    if checks:
        worst = max(
            checks,
            key=lambda check: (
                _CHECK_ORDER.index(check.get("verdict"))
                if check.get("verdict") in _CHECK_ORDER
                else 0
            ),
        )
        lines.append(line("reference check", _check_text(worst)))
    return lines


def diagnostics_lines(diagnostics: dict) -> list[str]:
    """Lines for a diagnostics record; tolerant of records read from older or foreign files."""
    lines = []
    estimate = diagnostics.get("fsr_estimate_hz")
    if _is_number(estimate):
        lines.append(line("sweep FSR", f"{frequency_text(estimate)} (the fringes' own period)"))
    ports = diagnostics.get("ports")
    for port in ports if isinstance(ports, list) else []:
        if not isinstance(port, dict):
            continue
        z = port.get("fringe_z")
        z_text = f"{_number(z)} standard errors" if _is_number(z) else "noiseless"
        lines.append(
            line(
                f"port {port.get('name')}",
                f"{port.get('status')}: fringe {_number(port.get('fringe_amplitude_w'))} W "
                f"({z_text}), noise {_number(port.get('noise_std_w'))} W",
            )
        )
    lines += _fit_lines(diagnostics.get("fit"), ports)
    lines += _reanchor_lines(diagnostics.get("reanchor"))
    notes = diagnostics.get("warnings")
    for note in notes if isinstance(notes, list) else []:
        if isinstance(note, dict):
            lines.append(line("warning", f"{note.get('cause')}: {note.get('message')}"))
    return lines

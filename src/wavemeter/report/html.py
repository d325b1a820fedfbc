"""Write the HTML report of a calibration and its figures as PNG files, safely.

Every output (the page and each PNG beside it) is checked before anything is drawn or
written: none may be an input file, a folder or device, or an existing file unless
``force`` is given. The figures are drawn first; then each file is written to a temporary
file and renamed into place, so a failure leaves no partial output.
"""

from __future__ import annotations

import io
from collections.abc import Mapping
from pathlib import Path

from ..atomic import STDOUT, atomic_path, check_output
from ..calibration.contract.base import BaseCalibrator
from ..exceptions import InputError
from .content import report_content
from .page import INPUT_ROLES, figure_names, render_page

__all__ = ["write_report", "report_paths", "DEFAULT_DPI"]

DEFAULT_DPI = 100


def report_paths(out_html, calibration: BaseCalibrator | None = None) -> list[Path]:
    """The files a report writes: the page, then ``<stem>-<figure>.png`` beside it, one per
    figure of ``calibration``'s report (default: the figures every report has)."""
    target = Path(out_html)
    return [target] + [
        target.with_name(f"{target.stem}-{name}.png") for name in figure_names(calibration)
    ]


def _input_files(sweep, test, input_files: Mapping | None) -> dict[str, object]:
    """Input files by role: those given, else the tables' ``source`` attributes."""
    files = {"sweep": getattr(sweep, "source", None), "test": getattr(test, "source", None)}
    given = dict(input_files or {})
    roles = [role for role, _ in INPUT_ROLES]
    unknown = sorted(set(given) - set(roles))
    if unknown:
        raise InputError(
            f"input_files has unknown roles {unknown}; allowed: {', '.join(roles)}",
            parameter="input_files",
        )
    files.update(given)
    return {role: path for role, path in files.items() if path is not None}


def png_bytes(figure, dpi: int) -> bytes:
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi)
    return buffer.getvalue()


def write_report(
    calibration: BaseCalibrator,
    sweep,
    test=None,
    out_html="report.html",
    *,
    port_phases_rad=None,
    dpi: int = DEFAULT_DPI,
    force: bool = False,
    input_files: Mapping | None = None,
) -> list[Path]:
    """Write an HTML report of a calibration with its figures, and the figures as PNG files.

    Parameters
    ----------
    calibration : BaseCalibrator
        A fitted calibration (learned, conventional, thermal, wide-band or a
        :class:`CalibrationSet`). A wide-band one adds the figures of its cross-validation
        curve and of its residual phase across the band.
    sweep : object
        The calibration sweep: any object with ``powers_w`` (N, n) in W and ``frequency_hz``
        or ``x_hz`` (N,) in Hz; ``monitor_w`` (N,) is used when present, ``source`` (its
        file) is named in the page. For a calibration that needs the chip temperature
        (thermal), also ``temperature_k`` (N,) in K: the report then adds the figure of
        the error against temperature and compares with the plain learned calibration.
    test : object, optional
        Test readings with known frequencies, same attributes. Default: evaluate on the
        sweep.
    out_html : str or Path
        The HTML file; PNGs are written beside it as ``<stem>-<figure>.png``.
    port_phases_rad : None or array_like, shape (n,)
        Nominal port phases of the design for the conventional comparison (rad).
    dpi : int
        Resolution of the PNG figures.
    force : bool
        Replace existing output files; without it an existing output is an error.
    input_files : mapping of str to str or Path, optional
        Files the report is made from, by role (``calibration``, ``sweep``, ``test``):
        named in the page's header and never overwritten. Default: the ``source``
        attributes of ``sweep`` and ``test``.

    Returns
    -------
    list of Path
        The HTML file, then the PNG files of the figures drawn.

    Raises
    ------
    InputError
        When the tables do not fit the calibration (ports, missing frequencies, bad values),
        when an output is an input file, not a regular file, in a missing folder, or exists
        and ``force`` is false (``parameter`` is ``"force"``); nothing is written then.
    NotFittedError
        When ``calibration`` is not fitted.

    Examples
    --------
    >>> import wavemeter as wm
    >>> device = wm.Interferometer.table1(ports=3, seed=7)  # a 3x3 meter with Table 1's impairments
    >>> f_hz = device.sweep_hz(200)  # 200 readings over one FSR near 193.4 THz
    >>> powers = device.powers(f_hz, power_w=1e-3, noise_w=5e-7, rng=1)  # (200, 3) in W
    >>> import tempfile
    >>> from pathlib import Path
    >>> from types import SimpleNamespace
    >>> cal = wm.Calibrator(fsr_hz=50e9).fit(powers, f_hz)
    >>> sweep = SimpleNamespace(powers_w=powers, frequency_hz=f_hz)  # or a wavemeter.io.Table
    >>> out = Path(tempfile.mkdtemp()) / "report.html"
    >>> written = wm.write_report(cal, sweep, out_html=out, dpi=40)
    >>> out in written, sorted({path.suffix for path in written})
    (True, ['.html', '.png'])
    """
    if str(out_html) == STDOUT:
        raise InputError(
            "the report is a page with PNG files beside it and cannot go to standard output: "
            "give a file name",
            parameter="out_html",
        )
    files = _input_files(sweep, test, input_files)
    outputs = report_paths(out_html, calibration)
    for path in outputs:
        check_output(path, inputs=list(files.values()), force=force)
    figures, summary = report_content(calibration, sweep, test, port_phases_rad)
    # the figures the calibration drew (one with no model of the fringes draws none of them)
    drawn = [name for name in figure_names(calibration) if name in figures]
    images = {name: png_bytes(figures[name], dpi) for name in drawn}
    page = render_page(calibration, summary, images, files)
    written = [outputs[0]] + [
        outputs[0].with_name(f"{outputs[0].stem}-{name}.png") for name in drawn
    ]
    for path, png in zip(written[1:], images.values(), strict=True):
        with atomic_path(path) as temporary:
            temporary.write_bytes(png)
    with atomic_path(written[0]) as temporary:
        temporary.write_text(page, encoding="utf-8")
    return written

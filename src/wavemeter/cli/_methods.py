"""The options that choose a calibration method and its settings, shared by ``calibrate`` and
``fleet calibrate``, and the :class:`~wavemeter.jobs.CalibrateOptions` they make.

``--method`` takes the tags of the registry (:func:`wavemeter.calibration.registered`, the
plug-ins of the ``wavemeter.calibrators`` entry points included), asked when a value is
checked and when ``--help`` is shown, never when the command is imported. Every
method-specific option is a setting of the method's calibrator by name (``SETTINGS``): the
job gives it to the calibrator, or refuses it, naming the methods that have it, when the
chosen one has none. None has a default of its own here: left out, a setting is the
method's default. ``--stage-ports`` counts columns from 1 and is checked against the FSRs
and the sweep's port columns here, in its own terms.
"""

from __future__ import annotations

import click

from ..exceptions import InputError
from ._common import PORT_PHASES, port_phases_rad
from ._params import FSRS, MAP_ORDER, PHASE_ORDER, STAGE_PORTS

__all__ = ["MethodParam", "METHOD", "SETTINGS", "method_options", "calibrate_options"]

#: option destination -> the calibrator setting it gives (the CLI's notation converted)
SETTINGS = {
    "fsr_tolerance": "fsr_tolerance",
    "retrieval": "retrieval",
    "phase_order": "phase_order",
    "map_order": "map_order",
    "stage_ports": "stage_ports",
    "max_order_error": "max_order_error",
    "temperature_std_k": "temperature_std_k",
    "port_phases_deg": "port_phases_rad",
}


class MethodParam(click.ParamType):
    """A calibration method: a tag of the registry, looked up when a value is checked or
    the choices are shown (so that importing the command imports no calibrator)."""

    name = "method"

    @staticmethod
    def tags() -> tuple[str, ...]:
        from ..calibration import registered

        return tuple(registered())

    def get_metavar(self, param, ctx=None) -> str:
        return f"[{'|'.join(self.tags())}]"

    def convert(self, value, param, ctx):
        tags = self.tags()
        if value in tags:
            return value
        self.fail(
            f"{value!r} is not a calibration method; methods (built in and installed "
            f"plug-ins): {', '.join(tags)}",
            param,
            ctx,
        )

    def shell_complete(self, ctx, param, incomplete):
        from click.shell_completion import CompletionItem

        return [CompletionItem(tag) for tag in self.tags() if tag.startswith(incomplete)]


METHOD = click.option(
    "--method",
    type=MethodParam(),
    default="learned",
    show_default=True,
    help="Calibration method, a tag of the registry: learned (the paper's linear map), "
    "conventional (the ideal map), thermal (the learned map with the chip temperature's "
    "effect; sweeps at several temperatures), wideband (one model across a band of many "
    "FSRs; readings then need a coarse frequency), cascade (stages of decreasing FSR: "
    "absolute frequency), reference_free, the baselines, and the methods of installed "
    "plug-ins.",
)


def method_options(command):
    """The options of the method and its settings: --method, --fsr, the settings (none
    with a default of its own: left out, the method's), --per-fsr."""
    options = [
        METHOD,
        click.option(
            "--fsr",
            type=FSRS,
            metavar="FSR[,FSR..]",
            help="Design FSR: 50GHz, '49.69 GHz'; a bare number is in Hz (5e10). A method of "
            "stages (cascade) takes one per stage, coarsest first. Default: the method's "
            "(50GHz; cascade 5THz,500GHz,50GHz).",
        ),
        click.option(
            "--fsr-tolerance",
            type=click.FloatRange(0, 1, min_open=True, max_open=True),
            help="Relative half width of the FSR search (default 0.2; not for conventional).",
        ),
        click.option(
            "--retrieval",
            type=click.Choice(("pinv", "ml")),
            help="Phase retrieval: pseudo-inverse (paper; the default) or cone-constrained "
            "maximum likelihood (reaches the Cramer-Rao bound also for ill-conditioned maps). "
            "Not for conventional.",
        ),
        click.option(
            "--phase-order",
            type=PHASE_ORDER,
            metavar="P",
            help="Order of the phase polynomial of --method wideband: 1 (linear phase, the "
            "paper's), 2 (adds dispersion) or higher. Default: chosen by cross-validation on "
            "held-out FSRs.",
        ),
        click.option(
            "--map-order",
            type=MAP_ORDER,
            metavar="J",
            help="Legendre order of the map's change across the band of --method wideband: "
            "0 (one map) or higher. Default: chosen by cross-validation on held-out FSRs.",
        ),
        click.option(
            "--stage-ports",
            type=STAGE_PORTS,
            help="Port columns of each stage of --method cascade, by position among the port "
            "columns read (from 1, in order), stages separated by '/' in the order of --fsr: "
            "1-3/4-6/7-9, 1,3,5/2,4,6/7-9. Default: consecutive blocks of equal size.",
        ),
        click.option(
            "--max-order-error",
            type=click.FloatRange(0, 1, min_open=True, max_open=True),
            metavar="P",
            help="Probability of a wrong fringe order above which --method cascade flags a "
            "reading ORDER_AMBIGUOUS, and the wrong-order rate at the sweep's noise above "
            "which it refuses a hand-over between stages (default 1e-6).",
        ),
        click.option(
            "--temperature-std-k",
            type=click.FloatRange(0, min_open=True),
            metavar="K",
            help="Noise of the temperature readings in use (K, --method thermal; default "
            "0.001): adds the fitted rate times it to each reading's frequency uncertainty.",
        ),
        PORT_PHASES,
        click.option(
            "--per-fsr",
            is_flag=True,
            help="Calibrate each FSR of a multi-FSR sweep on its own with the method (a "
            "calibration set; readings then need a coarse frequency).",
        ),
    ]
    for option in reversed(options):
        command = option(command)
    return command


def _stage_count(method: str, fsrs) -> int | None:
    """How many stages the cascade's design FSRs give (None: the method has none)."""
    if fsrs is not None:
        return len(fsrs)
    from ..jobs import method_settings

    default = method_settings(method).get("fsr_hz")
    return len(default) if isinstance(default, (tuple, list)) else None


def _check_stage_groups(stage_ports, method: str, fsrs) -> None:
    """Before any work: ``--stage-ports`` gives one group of 3 or more columns per FSR
    (for a method with stage ports; another refuses the setting)."""
    from ..jobs import method_settings

    if "stage_ports" not in method_settings(method):
        return
    stages = _stage_count(method, fsrs)
    if stages is not None and len(stage_ports) != stages:
        given = "--fsr has" if fsrs is not None else f"--method {method} has by default"
        raise InputError(
            f"--stage-ports gives the columns of {len(stage_ports)} stage(s) but {given} "
            f"{stages} FSRs: give one group of columns per FSR, separated by '/', in the "
            "order of the FSRs"
        )
    small = [index + 1 for index, stage in enumerate(stage_ports) if len(stage) < 3]
    if small:
        raise InputError(
            f"--stage-ports gives stage(s) {', '.join(map(str, small))} fewer than 3 columns; "
            "every stage needs 3 or more ports"
        )


def _stage_columns_check(stage_ports):
    """``check(layout)`` for the job: ``--stage-ports`` against the sweep's port columns,
    every one in a stage, none beyond them."""

    def check(layout) -> None:
        ports = len(layout.port_names)
        where = f"{layout.source} has {ports} port columns ({', '.join(layout.port_names)})"
        given = {position for stage in stage_ports for position in stage}
        beyond = sorted(given - set(range(1, ports + 1)))
        if beyond:
            raise InputError(
                f"--stage-ports names column(s) {', '.join(map(str, beyond))} but {where}; "
                "give positions from 1 to the number of port columns (choose the columns "
                "with --ports)"
            )
        missing = sorted(set(range(1, ports + 1)) - given)
        if missing:
            names = ", ".join(layout.port_names[position - 1] for position in missing)
            raise InputError(
                f"--stage-ports gives no stage column(s) {', '.join(map(str, missing))} "
                f"({names}), but {where}: give every port column to a stage, or read only "
                "the stages' columns with --ports"
            )

    return check


def calibrate_options(options: dict, **fields):
    """The job's options from the command's (``options``: click's values by destination),
    with ``fields`` of :class:`~wavemeter.jobs.CalibrateOptions` the command adds; and the
    ``check`` of the sweep's layout the options need (None: none).

    Returns
    -------
    (CalibrateOptions, callable or None)
    """
    from ..jobs import CalibrateOptions

    fsrs = options["fsr"]
    settings = {}
    for name, setting in SETTINGS.items():
        value = options.get(name)
        if name == "port_phases_deg":
            value = port_phases_rad(value)
        elif name == "stage_ports" and value is not None:
            _check_stage_groups(value, options["method"], fsrs)
            value = tuple(tuple(position - 1 for position in stage) for stage in value)
        if value is not None:
            settings[setting] = value
    check = None
    if options.get("stage_ports") is not None:
        check = _stage_columns_check(options["stage_ports"])
    calibrate = CalibrateOptions(
        method=options["method"],
        fsr_hz=None if fsrs is None else fsrs[0] if len(fsrs) == 1 else tuple(fsrs),
        settings=settings,
        per_fsr=options["per_fsr"],
        **fields,
    )
    return calibrate, check

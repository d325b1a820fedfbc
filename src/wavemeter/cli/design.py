"""`wavemeter design`: the fewest cascade stages that read a band at a wrong-order rate.

Prints :func:`wavemeter.design_cascade`'s design as a table (one row per stage: FSR, ratio
to the next, stage frequency std, margin and rate of its hand-over), or as JSON with the
units in the key names.
"""

from __future__ import annotations

import json

import click

from ._common import setting
from ._params import BAND, FSR, POWER


@click.command()
@click.option(
    "--band",
    "band_hz",
    required=True,
    type=BAND,
    help="The band readings come from, LOW:HIGH, each end a frequency or a vacuum "
    "wavelength: 191THz:195.4THz, 1530nm:1565nm.",
)
@click.option(
    "--finest-fsr",
    "finest_fsr_hz",
    required=True,
    type=FSR,
    metavar="FREQUENCY",
    help="FSR of the finest (last) stage: 50GHz; a bare number is in Hz.",
)
@setting(
    "--noise",
    "5e-7W",
    POWER,
    "Detector noise standard deviation per port and reading: 0.5uW, 5e-7W; a bare number is in W.",
    dest="noise_w",
)
@setting(
    "--power",
    "1mW",
    POWER,
    "Source power entering the cascade, split equally among the stages: 1mW, 0dBm; a bare "
    "number is in W.",
    dest="power_w",
)
@setting("--ports", 3, click.IntRange(3, 64), "Ports per stage.")
@setting(
    "--rate",
    1e-9,
    click.FloatRange(0, 1, min_open=True, max_open=True),
    "Requested wrong-order rate per reading (the probability that some stage picks the "
    "wrong fringe order).",
    dest="wrong_order_rate",
)
@setting(
    "--noise-factor",
    2.0,
    click.FloatRange(1.0),
    "The stages' noise over the ideal bound to design for (2 covers Table 1 stages at their "
    "noisiest phase; 1: ideal stages).",
    dest="noise_factor",
)
@setting(
    "--fsr-tolerance",
    0.1,
    click.FloatRange(0.0, 1.0, max_open=True),
    "Relative FSR error of the fabricated stages to design for (0.1: twice Table 1's 5 % "
    "delay spread; 0: exact FSRs).",
    dest="fsr_tolerance",
)
@click.option(
    "--stages",
    type=click.IntRange(1, 8),
    help="Force this many stages and show their best design, met or not (default: the "
    "fewest that meet --rate).",
)
@click.option("--json", "as_json", is_flag=True, help="Print the design as JSON.")
def design(
    band_hz,
    finest_fsr_hz,
    noise_w,
    power_w,
    ports,
    wrong_order_rate,
    noise_factor,
    fsr_tolerance,
    stages,
    as_json,
):
    """The fewest cascade stages that read a band at a wrong-order rate.

    Stages --noise-factor times noisier than ideal with FSRs off by up to --fsr-tolerance,
    the source power split equally among them; the finest FSR is given, the others
    geometric, the coarsest chosen to minimise the predicted wrong-order rate.

    \b
    Example:
      wavemeter design --band 191THz:195.4THz --finest-fsr 50GHz --noise 0.5uW
      wavemeter design --band 1530nm:1565nm --finest-fsr 50GHz --rate 1e-12 --json
    """
    from ..model.cascade_design import design_cascade

    found = design_cascade(
        band_hz,
        finest_fsr_hz,
        ports=ports,
        power_w=power_w,
        noise_w=noise_w,
        wrong_order_rate=wrong_order_rate,
        noise_factor=noise_factor,
        fsr_tolerance=fsr_tolerance,
        stages=stages,
    )
    if as_json:
        click.echo(json.dumps(found.to_dict(), indent=1))
        return
    click.echo(str(found))
    if not found.meets_rate:
        click.echo(
            f"warning: [rate_not_met] {found.stages} stage(s) do not reach the requested rate; "
            "leave out --stages for the fewest that do",
            err=True,
        )


command = design

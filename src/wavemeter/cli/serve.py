"""`wavemeter serve`: the live instrument, a service many clients read and control at once.

Builds a :class:`wavemeter.service.Server` from the options (a calibration file and a line
source, or the simulated meter of ``--simulate``), prints the addresses it bound, and serves
until SIGTERM or Ctrl-C, which flush the logs and exit 0. Bad options, an address other than
the loopback without a token, and a source whose header the calibration cannot read are
one ``error:`` line and exit code 2.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import click

from ..exceptions import InputError
from ._common import QUIET, column_options, column_request, say
from ._params import DURATION, FREQUENCY
from ._readings import checked_calibration, reading_input_options

#: the service's defaults (wavemeter.service.addresses; not imported here, so that
#: ``wavemeter serve --help`` loads no network library)
DEFAULT_PUBLISH = "tcp://127.0.0.1:5560"
DEFAULT_CONTROL = "tcp://127.0.0.1:5561"
DEFAULT_HTTP = "127.0.0.1:8560"


@click.command()
@click.argument(
    "calibration_file", metavar="[CAL]", required=False, type=click.Path(dir_okay=False)
)
@click.option(
    "--simulate",
    is_flag=True,
    help="Serve a simulated Table 1 meter, calibrated at "
    "start-up, reading one drifting laser per channel (no hardware, no CAL).",
)
@click.option(
    "--source",
    metavar="-|FILE|tcp://HOST:PORT",
    help="Where readings come from: "
    "standard input (-, the default with CAL), a file, or a TCP port that "
    "acquisition programs connect to and write lines into.",
)
@click.option("--follow", is_flag=True, help="Keep reading lines appended to the --source FILE.")
@click.option(
    "--rate",
    "rate_hz",
    type=FREQUENCY,
    default="1kHz",
    show_default=True,
    help="Readings per second of --simulate (all channels together).",
)
@click.option(
    "--channels",
    type=click.IntRange(1, 256),
    default=1,
    show_default=True,
    help="Switch inputs the source cycles through: reading k is channel k mod N.",
)
@click.option(
    "--channel-column",
    metavar="COL",
    help="A column giving each reading's channel (0, 1, ...) instead of a schedule.",
)
@click.option(
    "--publish",
    default=DEFAULT_PUBLISH,
    show_default=True,
    metavar="tcp://HOST:PORT",
    help="Where readings are published (port 0: a free one).",
)
@click.option(
    "--control",
    default=DEFAULT_CONTROL,
    show_default=True,
    metavar="tcp://HOST:PORT",
    help="Where control requests are answered.",
)
@click.option(
    "--http",
    default=DEFAULT_HTTP,
    show_default=True,
    metavar="HOST:PORT|off",
    help="Where the dashboard and /metrics are served; off: not at all.",
)
@click.option(
    "--log",
    "log_dir",
    metavar="DIR",
    type=click.Path(file_okay=False),
    help="Log every reading to per-channel Parquet files in DIR.",
)
@click.option("--log-powers", is_flag=True, help="Log the port powers too (with --log).")
@click.option(
    "--log-rotate",
    "log_rotate_s",
    type=DURATION,
    default="3600s",
    show_default=True,
    help="Start a new log file per channel after this long (s, ms).",
)
@click.option(
    "--log-rotate-mb",
    type=click.FloatRange(min=1, min_open=False),
    default=256,
    show_default=True,
    help="... or once a channel's file holds this many MB.",
)
@click.option(
    "--token",
    help="A secret that clients, the dashboard and TCP sources must give; "
    "needed to bind anywhere but 127.0.0.1.",
)
@click.option(
    "--token-file",
    type=click.Path(dir_okay=False),
    help="Read the token from a file (keeps it out of the process list).",
)
@click.option(
    "--signal-timeout",
    "signal_timeout_s",
    type=DURATION,
    default="1s",
    show_default=True,
    help="A channel without a reading for this long has no signal.",
)
@click.option(
    "--hwm",
    type=click.IntRange(1, 10_000_000),
    default=10000,
    show_default=True,
    help="Messages queued per subscriber before its messages are dropped (counted).",
)
@click.option(
    "--name", "names", multiple=True, metavar="N=NAME", help="Name channel N (repeat for more)."
)
@click.option(
    "--seed", type=int, default=7, show_default=True, help="Seed of the simulated meter and lasers."
)
@click.option(
    "--open/--no-open",
    "open_browser",
    default=None,
    help="Open the dashboard in a browser (default: with --simulate at a desktop).",
)
@reading_input_options
@column_options(axis=False, drop_invalid=False)
@QUIET
def serve(
    calibration_file,
    simulate,
    source,
    follow,
    rate_hz,
    channels,
    channel_column,
    publish,
    control,
    http,
    log_dir,
    log_powers,
    log_rotate_s,
    log_rotate_mb,
    token,
    token_file,
    signal_timeout_s,
    hwm,
    names,
    seed,
    open_browser,
    coarse_column,
    coarse_hz,
    temperature_k,
    **options,
):
    """Serve a meter live: publish every reading to many clients, answer control
    requests, log, and show a dashboard.

    Readings come from the simulated meter (--simulate) or, with a calibration CAL, from
    lines of port readings (the columns and rules of `wavemeter stream`) on standard
    input, in a file (--follow to keep reading it) or from TCP connections. Each
    reading is published on its channel's topic (ch/N/) with its sequence number, source
    and service times, frequency_hz, frequency_std_hz, flags and the calibration's extra
    outputs; clients read them with wavemeter.service.Client. Every address binds to
    127.0.0.1 unless told otherwise, and anything else needs --token. SIGTERM or Ctrl-C
    flush the logs and exit 0.

    \b
    Example:
      wavemeter serve --simulate --channels 3
      logger | wavemeter serve chip.wmcal.json --log logs/
      wavemeter serve chip.wmcal.json --source tcp://127.0.0.1:5570 --channels 4
      wavemeter serve chip.wmcal.json --source log.csv --follow --channel-column channel
    """
    quiet = options["quiet"]
    token = _token(token, token_file)
    _check_choices(calibration_file, simulate, source, follow, log_dir, log_powers, channel_column)
    from ..service.server import Server

    http = None if http.strip().lower() in ("off", "none", "") else http
    names = _names(names)
    if simulate:
        from ..service.simulated import simulated_meter

        device, calibration = simulated_meter(seed)
        label = "simulated Table 1 meter"
    else:
        calibration, _ = checked_calibration(
            calibration_file, coarse_column, coarse_hz, temperature_k, None, options
        )
        label = calibration_file
    server = Server(
        calibration,
        publish=publish,
        control=control,
        http=http,
        log=log_dir,
        log_powers=log_powers,
        token=token,
        signal_timeout_s=signal_timeout_s,
        hwm=hwm,
        log_options={"rotate_s": log_rotate_s, "rotate_bytes": int(log_rotate_mb * 2**20)},
        channel_names=names,
        calibration_path=None if simulate else str(calibration_file),
    )
    if simulate:
        from ..service.simulated import SimulatedSource

        server.add_source(
            SimulatedSource(
                device,
                calibration,
                server.submit_threadsafe,
                rate_hz=rate_hz,
                channels=channels,
                seed=seed,
            )
        )
    else:
        request = column_request(options, coarse=coarse_column)
        server.add_source(
            _line_source(
                server, source, follow, request, channels, channel_column, coarse_hz, temperature_k
            )
        )

    def ready(addresses) -> None:
        dashboard = addresses.get("http")
        say(
            quiet,
            f"serving {label}: publish {addresses['publish']}, control "
            f"{addresses['control']}"
            + (f", source {addresses['source']}" if "source" in addresses else ""),
            err=True,
        )
        if dashboard:
            say(
                quiet,
                f"dashboard: {dashboard}" + (" (add ?token=TOKEN)" if token else ""),
                err=True,
            )
            if open_browser or (open_browser is None and simulate and _desktop()):
                import webbrowser

                webbrowser.open(dashboard + (f"?token={token}" if token else ""))

    server.run(on_ready=ready)
    total = sum(channel.readings for channel in server.channels.values())
    say(
        quiet,
        f"stopped: published {total} readings on {len(server.channels)} channel(s)"
        + (f", logged to {log_dir}" if log_dir else ""),
        err=True,
    )


def _token(token, token_file):
    if token is not None and token_file is not None:
        raise InputError("give the token once: --token or --token-file, not both")
    if token_file is not None:
        token = Path(token_file).read_text(encoding="utf-8").strip()
        if not token:
            raise InputError(f"{token_file}: the token file is empty; write the token in it")
    if token is not None and not token.strip():
        raise InputError("--token is empty; give a secret, or leave --token out")
    return token


def _check_choices(
    calibration_file, simulate, source, follow, log_dir, log_powers, channel_column
) -> None:
    if simulate and calibration_file is not None:
        raise InputError("--simulate calibrates its own simulated meter: give no CAL with it")
    if not simulate and calibration_file is None:
        raise InputError("give a calibration file CAL (and a --source), or --simulate")
    if simulate and (source is not None or channel_column is not None):
        raise InputError("--simulate is its own source: leave --source and --channel-column out")
    if follow and (source is None or source == "-" or source.startswith("tcp://")):
        raise InputError("--follow reads a file: give it with --source FILE")
    if log_powers and log_dir is None:
        raise InputError("--log-powers adds the port powers to the log: give --log DIR")


def _names(pairs) -> dict[int, str]:
    names = {}
    for pair in pairs:
        number, _, name = pair.partition("=")
        if not number.strip().isdigit() or not name.strip():
            raise InputError(f"--name {pair!r}: expected N=NAME, e.g. --name 0=Ti:Sa")
        names[int(number)] = name.strip()
    return names


def _line_source(
    server, source, follow, request, channels, channel_column, coarse_hz, temperature_k
):
    from ..service.addresses import tcp_host_port
    from ..service.lines import LineParser
    from ..service.sources import TcpLineSource, ThreadLineSource

    def parser(name):
        return LineParser(
            name,
            request,
            channels=channels,
            channel_column=channel_column,
            coarse_hz=coarse_hz,
            temperature_k=temperature_k,
        )

    if source is not None and source.startswith("tcp://"):
        host, port = tcp_host_port(source)
        from ..service.addresses import check_binds

        check_binds({"source": source}, server.token)
        return TcpLineSource(server, host, port, parser)
    if source is None or source == "-":
        return ThreadLineSource(server, parser("<stdin>"))
    if not Path(source).is_file():
        raise InputError(f"{source}: no such file (--source)")
    return ThreadLineSource(server, parser(source), source, follow=follow)


def _desktop() -> bool:
    """Whether a browser window could open here (an interactive session with a display)."""
    graphical = sys.platform in ("darwin", "win32") or bool(
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    )
    return graphical and sys.stdin.isatty() and sys.stderr.isatty()


command = serve

"""The service: sources in, channels, publish, control, log, metrics and dashboard out.

A :class:`Server` runs one asyncio loop (in the calling thread with :meth:`Server.run`, or
in a thread of its own with :meth:`Server.start`). Everything that touches the channels runs
on that loop: a block of raw readings from a source (a line source, the simulated meter,
:meth:`Server.feed`) is read out with the calibration in force, numbered per channel,
published, queued for the log, counted in the metrics and folded into the dashboard's trace,
before the next block. Threads hand their blocks over through :meth:`submit_threadsafe`
(blocks waiting together are read out together: batching comes with load). A reload swaps
the calibration between two blocks. Control requests are answered by :mod:`.requests` and
:mod:`.lock_requests`; channels with an output can be locked (:mod:`.locks`), and a
reference channel keeps the calibration anchored (:mod:`.anchoring`).
"""

from __future__ import annotations

import asyncio
import collections
import gc
import secrets
import signal
import threading
import time
from pathlib import Path

import numpy as np
import zmq
import zmq.asyncio

from ..exceptions import InputError, WavemeterError
from .addresses import (
    DEFAULT_CONTROL,
    DEFAULT_HTTP,
    DEFAULT_PUBLISH,
    check_binds,
    http_host_port,
)
from .anchoring import Anchoring
from .blocks import RowBlock
from .channels import NO_SIGNAL, Channel
from .control import Control
from .dashboard import Trace, channel_view
from .encoding import HEARTBEAT_S
from .lines import LineCounts, LineParser
from .lock_requests import register_lock_requests
from .locks import LockManager
from .metrics import Metrics
from .parquet_log import ParquetLog
from .publisher import DEFAULT_HWM, Publisher
from .readout import CalibrationReader
from .requests import register_requests

__all__ = ["Server", "DEFAULT_PUBLISH", "DEFAULT_CONTROL", "DEFAULT_HTTP", "SIGNAL_TIMEOUT_S"]

#: seconds without a reading after which a channel has no signal
SIGNAL_TIMEOUT_S = 1.0
_WATCH_S = 0.05


class Server:
    """A live wavelength-meter service.

    Parameters
    ----------
    calibration : BaseCalibrator
        The calibration readings are read out with.
    publish, control : str
        ZeroMQ endpoints to bind (``tcp://127.0.0.1:0``: a free port).
    pub : str, optional
        A plain ZeroMQ PUB socket to bind as well, for SUB sockets (:mod:`.plain_pub`);
        None: none.
    http : str or None
        ``HOST:PORT`` of the dashboard and ``/metrics``; None: no HTTP.
    log : str or Path, optional
        A folder for per-channel Parquet logs.
    log_powers : bool
        Log the port powers (``P1_w``, ...) too.
    token : str, optional
        Needed by control requests, subscriptions, HTTP and TCP sources; required for any
        address other than the loopback.
    signal_timeout_s : float
        A channel without a reading for this long has ``no signal``.
    hwm : int
        Messages queued per subscriber before its messages are dropped.
    channel_names : mapping of int to str, optional
        Names of channels.
    calibration_path : str, optional
        Where the calibration came from (shown in status).
    log_options : dict, optional
        ``flush_s``, ``rotate_s``, ``rotate_bytes`` of the log.
    outputs : mapping of int to (sink, str), optional
        The channels that can be locked: each one's output sink (:mod:`.outputs`) and what
        it is.
    reference : dict, optional
        A reference channel: ``channel``, ``frequency_hz`` and the settings of
        :class:`~.reference.ReferenceKeeper`.

    Raises
    ------
    InputError
        For an address other than the loopback without a token, or a malformed address; a
        reference the calibration cannot be re-anchored to.
    """

    def __init__(
        self,
        calibration,
        *,
        publish: str = DEFAULT_PUBLISH,
        control: str = DEFAULT_CONTROL,
        http: str | None = DEFAULT_HTTP,
        pub: str | None = None,
        log=None,
        log_powers: bool = False,
        token: str | None = None,
        signal_timeout_s: float = SIGNAL_TIMEOUT_S,
        hwm: int = DEFAULT_HWM,
        channel_names=None,
        calibration_path: str | None = None,
        log_options: dict | None = None,
        outputs: dict | None = None,
        reference: dict | None = None,
    ):
        check_binds({"publish": publish, "control": control, "http": http, "pub": pub}, token)
        if token is not None and not token.strip():
            raise InputError("the token is empty; give a non-empty token", parameter="token")
        self.calibration = calibration
        self.calibration_path = calibration_path
        self.endpoints = {"publish": publish, "control": control, "http": http, "pub": pub}
        self.log_folder = log
        self.log_powers = log_powers
        self.log_options = log_options or {}
        self.token = token
        self.signal_timeout_s = signal_timeout_s
        self.hwm = hwm
        self.run_id = secrets.token_hex(4)
        self.started = time.time()
        self.channels: dict[int, Channel] = {}
        self.traces: dict[int, Trace] = {}
        self.names = {int(k): str(v) for k, v in (channel_names or {}).items()}
        self.sources: list = []
        self.line_totals = LineCounts()
        self.metrics = Metrics()
        self.addresses: dict[str, str] = {}
        self.failure: WavemeterError | None = None
        self.log = None
        self._reader = CalibrationReader(calibration)
        self._queue: collections.deque = collections.deque()
        self._draining = False
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stopping: asyncio.Event | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._start_error: BaseException | None = None
        self.locks = LockManager(self, outputs or {})
        self.anchoring = None if reference is None else Anchoring(self, **reference)

    # ------------------------------------------------------------------ running
    def add_source(self, source) -> None:
        """Add a source (before the server starts)."""
        self.sources.append(source)

    def run(self, *, on_ready=None) -> None:
        """Serve in this thread until SIGTERM or SIGINT (or :meth:`stop`); logs flushed.

        Once bound, start-up's objects are frozen out of the collector's passes
        (:func:`gc.freeze`): a full pass then costs ~0.01 ms, not 40-95 ms.

        Parameters
        ----------
        on_ready : callable, optional
            Called with the bound addresses once every socket is bound.

        Raises
        ------
        WavemeterError
            What made a source fail for good (a header the calibration cannot read).
        """
        asyncio.run(self._main(on_ready, signals=True))
        if self.failure is not None:
            raise self.failure

    def start(self) -> Server:
        """Serve in a thread of its own; return once every socket is bound."""
        self._thread = threading.Thread(
            target=lambda: asyncio.run(self._main(None, signals=False)),
            name="wavemeter-serve",
            daemon=True,
        )
        self._thread.start()
        self._ready.wait()
        if self._start_error is not None:
            raise self._start_error
        return self

    def stop(self) -> None:
        """Stop serving (any thread; again does nothing): sources stopped, readings waiting
        read out, logs written, sockets closed."""
        if self._loop is not None and self._stopping is not None and not self._loop.is_closed():
            self._loop.call_soon_threadsafe(self._stopping.set)
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()

    def __enter__(self) -> Server:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    async def _main(self, on_ready, signals: bool) -> None:
        self._loop = asyncio.get_running_loop()
        self._stopping = asyncio.Event()
        context = zmq.asyncio.Context()
        tasks, runner = [], None
        try:
            try:
                runner = await self._bind(context, tasks)
            except BaseException as exc:
                self._start_error = exc
                raise
            finally:
                self._ready.set()
            if signals:
                for number in (signal.SIGTERM, signal.SIGINT):
                    self._loop.add_signal_handler(number, self._stopping.set)
                gc.freeze()  # the process is the service's (run's docstring)
            if on_ready is not None:
                on_ready(dict(self.addresses))
            await self._stopping.wait()
        finally:
            if signals:
                for number in (signal.SIGTERM, signal.SIGINT):
                    self._loop.remove_signal_handler(number)
            await self._shutdown(tasks, runner, context)

    async def _bind(self, context, tasks: list):
        self.publisher = Publisher(
            context, self.endpoints["publish"], token=self.token, hwm=self.hwm, run=self.run_id
        )
        self.publisher.on_dropped = self._dropped
        self.addresses["publish"] = self.publisher.address
        if self.endpoints["pub"] is not None:
            from .plain_pub import PlainPublisher

            self.publisher.plain = PlainPublisher(
                context, self.endpoints["pub"], token=self.token, hwm=self.hwm
            )
            self.addresses["pub"] = self.publisher.plain.address
        self.control = Control(context, self.endpoints["control"], token=self.token)
        self.addresses["control"] = self.control.address
        register_requests(self)
        register_lock_requests(self)
        runner = None
        if self.endpoints["http"] is not None:
            from aiohttp import web

            from .http import make_app

            host, port = http_host_port(self.endpoints["http"])
            runner = web.AppRunner(make_app(self), access_log=None)
            await runner.setup()
            site = web.TCPSite(runner, host, port)
            await site.start()
            bound = site._server.sockets[0].getsockname()
            self.addresses["http"] = f"http://{host}:{bound[1]}/"
        if self.log_folder is not None:
            self.log = ParquetLog(self.log_folder, self.run_id, **self.log_options)
        if self.anchoring is not None:
            self.anchoring.start(None if self.log is None else Path(self.log_folder))
        for source in self.sources:
            if hasattr(source, "register_requests"):
                source.register_requests(self.control)
            if hasattr(source, "start_async"):
                await source.start_async()
                self.addresses["source"] = source.name
            else:
                source.start()
        tasks += [
            asyncio.ensure_future(self.publisher.serve()),
            asyncio.ensure_future(self.control.serve()),
            asyncio.ensure_future(self._watch()),
        ]
        return runner

    async def _shutdown(self, tasks, runner, context) -> None:
        for source in self.sources:
            source.stop()
        self._drain()
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        if runner is not None:
            await runner.cleanup()
        self.locks.close()
        if self.log is not None:
            await asyncio.get_running_loop().run_in_executor(None, self.log.close)
        for part in ("publisher", "control"):
            if hasattr(self, part):
                getattr(self, part).close()
        if hasattr(self, "publisher") and self.publisher.plain is not None:
            self.publisher.plain.close()
        context.term()

    def fail_threadsafe(self, error: WavemeterError) -> None:
        """End the service because a source failed for good (any thread); :meth:`run`
        raises ``error`` once everything is stopped."""

        def fail():
            self.failure = error
            self._stopping.set()

        self._loop.call_soon_threadsafe(fail)

    # ------------------------------------------------------------------ readings
    def feed(self, powers, time_s=None, channel: int = 0) -> None:
        """Hand the service readings taken by lab code (any thread).

        Parameters
        ----------
        powers : array_like, shape (ports,) or (N, ports)
            Port powers in the calibration's unit (W for a sweep read in W).
        time_s : float or array_like, shape (N,), optional
            When each was taken (s since the epoch); default now.
        channel : int
            Their channel (>= 0).

        Raises
        ------
        InputError
            For powers of another number of ports than the calibration's, or a negative
            channel. A reading that cannot be read (NaN, no light) is published as INVALID.
        """
        powers_w = np.atleast_2d(np.asarray(powers, dtype=float))
        ports = len(self.calibration.port_names_)
        if powers_w.ndim != 2 or powers_w.shape[1] != ports:
            raise InputError(
                f"powers of shape {np.shape(powers)}: expected ({ports},) or (N, {ports}) for "
                f"this calibration's {ports} ports",
                parameter="powers",
            )
        if int(channel) != channel or channel < 0:
            raise InputError(f"channel {channel!r}: expected an integer >= 0", parameter="channel")
        n = len(powers_w)
        if time_s is None:
            times = np.full(n, time.time_ns())
        else:
            times = np.round(np.broadcast_to(np.asarray(time_s, dtype=float), n) * 1e9)
        block = RowBlock(
            channel=np.full(n, int(channel), dtype=np.int64),
            powers_w=powers_w,
            invalid=~np.isfinite(powers_w).all(axis=1),
            source_time_ns=np.asarray(times, dtype=np.int64),
        )
        self.submit_threadsafe(block)

    def submit_threadsafe(self, block: RowBlock) -> None:
        """Queue a block from another thread; the loop reads out what is queued together."""
        if self._loop is None or self._loop.is_closed():
            raise InputError("the server is not running: start it first (start() or run())")
        block.arrived = time.perf_counter()
        self._queue.append(block)
        if not self._draining:
            self._draining = True
            self._loop.call_soon_threadsafe(self._drain)

    def submit(self, block: RowBlock) -> None:
        """Read out a block now (on the loop)."""
        block.arrived = time.perf_counter()
        self._process(block)

    def _drain(self) -> None:
        self._draining = False
        blocks = []
        while self._queue:
            blocks.append(self._queue.popleft())
        if blocks:
            self._process(RowBlock.concat(blocks))

    def _process(self, block: RowBlock) -> None:
        reader = self._reader
        for index, part in block.by_channel():
            channel = self.channel(index)
            batch = channel.process(part, reader, self.run_id)
            self.publisher.publish(batch)
            channel.account(batch)
            if self.log is not None:
                columns = batch.columns
                if self.log_powers:
                    powers = part.powers_w
                    columns = {
                        **columns,
                        **{f"P{k + 1}_w": powers[:, k] for k in range(powers.shape[1])},
                    }
                self.log.append(index, columns)
            self.traces[index].add(batch)
            if self.anchoring is not None and index == self.anchoring.channel:
                self.anchoring.take(part, batch)
            latency = time.perf_counter() - block.arrived
            frequency = batch.columns["frequency_hz"]
            self.metrics.batch(str(index), batch.columns["flags"], latency, float(frequency[-1]))

    def channel(self, index: int) -> Channel:
        """Channel ``index``, made now if no reading has come for it yet (to attach a
        processor before the first reading: ``server.channel(0).processors.append(...)``;
        on the loop, or before the server starts)."""
        channel = self.channels.get(index)
        if channel is None:
            channel = self.channels[index] = Channel(index, self.names.get(index))
            self.traces[index] = Trace()
        return channel

    def _dropped(self, index: int, readings: int) -> None:
        self.channels[index].dropped += readings
        self.metrics.dropped.labels(str(index)).inc(readings)

    async def _watch(self) -> None:
        """Statuses, rates and heartbeats, every few tens of milliseconds."""
        beat = 0.0
        while True:
            now = time.monotonic()
            changed = [c.watch(self.signal_timeout_s, now) for c in list(self.channels.values())]
            self.locks.watch(now)
            if any(changed):
                self.publisher.publish_status(self.channel_list())
            if now - beat >= HEARTBEAT_S:
                beat = now
                self.publisher.heartbeat()
                self.update_gauges()
            await asyncio.sleep(_WATCH_S)

    # ------------------------------------------------------------------ views
    def update_gauges(self) -> None:
        """Gauges read at a scrape: subscribers, rates, signal, the log."""
        self.metrics.subscribers.set(len(self.publisher.subscribers))
        for index, channel in self.channels.items():
            self.metrics.rate.labels(str(index)).set(channel.rate_hz)
            self.metrics.signal.labels(str(index)).set(0 if channel.status == NO_SIGNAL else 1)
        if self.log is not None:
            self.metrics.logged.set(self.log.rows)

    def channel_list(self) -> list[dict]:
        """Every channel's number, name, topic and status."""
        return [
            {"channel": c.index, "name": c.name, "topic": f"ch/{c.index}/", "status": c.status}
            for c in sorted(self.channels.values(), key=lambda c: c.index)
        ]

    def note_lines(self, parser: LineParser) -> None:
        """Keep the counts of a line source that closed."""
        totals, counts = self.line_totals, parser.counts
        totals.lines += counts.lines
        totals.invalid += counts.invalid
        totals.unroutable += counts.unroutable
        for reason, count in counts.reasons.items():
            totals.reasons[reason] = totals.reasons.get(reason, 0) + count

    def line_parsers(self) -> list[LineParser]:
        """The parsers of the line sources now open."""
        parsers = []
        for source in self.sources:
            parsers += getattr(source, "parsers", [getattr(source, "parser", None)])
        return [p for p in parsers if p is not None]

    def status(self) -> dict:
        """The service's status, JSON-ready."""
        from .requests import status_of

        return status_of(self)

    def dashboard_view(self, sent: dict[int, int]) -> dict:
        """What the dashboard shows, with the trace bins after ``sent[channel]``."""
        return {
            "time_ns": time.time_ns(),
            "run": self.run_id,
            "subscribers": len(self.publisher.subscribers),
            "sources": [{"name": source.name, "state": source.state} for source in self.sources],
            "channels": [
                channel_view(
                    channel,
                    self.traces[index],
                    sent.get(index, 0),
                    lock=self.locks.view(index),
                    reference=self.anchoring and self.anchoring.view(index),
                )
                for index, channel in sorted(self.channels.items())
            ],
        }

    def use_calibration(self, calibration, path: str | None) -> None:
        """Swap the calibration (on the loop, between two blocks); a reference re-anchors
        the new one from then on."""
        self.anchor(calibration)
        self.calibration_path = path
        if self.anchoring is not None:
            self.anchoring.rebase(calibration)

    def anchor(self, calibration) -> None:
        """Read with a re-anchored copy of the calibration from the next block on."""
        self._reader = CalibrationReader(calibration)
        self.calibration = calibration

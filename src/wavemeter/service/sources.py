"""Line sources: standard input, a file (read to its end, or followed), a TCP port.

Each source reads text lines and turns them into :class:`RowBlock` s with its own
:class:`LineParser` (the column rules of ``wavemeter stream``), then hands them to the
server. Standard input and files are read by a thread (``os.read`` of what is there, or
:func:`wavemeter.jobs.follow_lines`); the TCP source is an asyncio server: an acquisition
program connects and writes a header line and then readings, and several may at once.
A header the calibration cannot read ends a standard-input or file source as a start-up
error would; a TCP connection gets an ``error:`` line and is closed. With a token, a TCP
connection must first send the line ``#token TOKEN``.
"""

from __future__ import annotations

import asyncio
import codecs
import hmac
import os
import threading
import time
from pathlib import Path

from ..exceptions import WavemeterError
from ..jobs import follow_lines
from .lines import LineParser

__all__ = ["ThreadLineSource", "TcpLineSource", "READ_BYTES"]

READ_BYTES = 1 << 16


class _Lines:
    """Bytes in, whole lines out (UTF-8, undecodable bytes replaced)."""

    def __init__(self):
        self.decoder = codecs.getincrementaldecoder("utf-8")(errors="replace")
        self.held = ""

    def feed(self, data: bytes, final: bool = False) -> list[str]:
        text = self.held + self.decoder.decode(data, final=final)
        lines = text.split("\n")
        self.held = "" if final else lines.pop()
        return [line for line in lines if line or not final]


class _Feeder:
    """Lines to blocks for one parser: the header first, then rows to ``submit``."""

    def __init__(self, server, parser: LineParser, submit):
        self.server = server
        self.parser = parser
        self.submit = submit

    def lines(self, lines: list[str]) -> None:
        if self.parser.header is None:
            lines = self.parser.start(lines, self.server.calibration)
            if self.parser.header is None:
                return
        if lines:
            block = self.parser.rows(lines, time.time_ns())
            if block is not None:
                self.submit(block)


class ThreadLineSource:
    """Standard input (``path`` None or ``"-"``) or a file, read by a thread.

    Parameters
    ----------
    server : Server
        Where the readings go.
    parser : LineParser
        The source's column rules.
    path : str or Path, optional
        A file; None or ``"-"``: standard input.
    follow : bool
        Keep reading what is appended to the file (like ``tail -f``).
    """

    def __init__(self, server, parser: LineParser, path=None, *, follow: bool = False):
        self.server = server
        self.parser = parser
        self.path = None if path in (None, "-") else Path(path)
        self.follow = follow
        self.state = "starting"
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="wavemeter-source", daemon=True)
        if self.path is not None and follow:
            self._lines = follow_lines(self.path, stop=self._stop)
        elif self.path is not None:
            try:
                self._file = open(self.path, "rb")  # noqa: SIM115 (closed by the thread)
            except OSError as exc:
                raise WavemeterError(f"{self.path}: cannot read ({exc.strerror})") from None

    @property
    def name(self) -> str:
        return self.parser.name

    def start(self) -> None:
        self.state = "running"
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()

    def _run(self) -> None:
        feeder = _Feeder(self.server, self.parser, self.server.submit_threadsafe)
        try:
            if self.path is not None and self.follow:
                for line in self._lines:
                    feeder.lines([line])
            else:
                self._read(feeder)
            self.state = "ended"
        except WavemeterError as exc:
            self.state = "failed"
            self.server.fail_threadsafe(exc)

    def _read(self, feeder: _Feeder) -> None:
        handle = self._file if self.path is not None else None
        descriptor = 0 if handle is None else handle.fileno()
        lines = _Lines()
        try:
            while not self._stop.is_set():
                data = os.read(descriptor, READ_BYTES)
                feeder.lines(lines.feed(data, final=not data))
                if not data:
                    return
        finally:
            if handle is not None:
                handle.close()


class TcpLineSource:
    """A TCP port that acquisition programs connect to and write lines into.

    Parameters
    ----------
    server : Server
        Where the readings go.
    host, port : str, int
        Where to listen (port 0: a free one).
    parser_factory : callable
        ``parser_factory(name)`` makes the :class:`LineParser` of a new connection.
    """

    def __init__(self, server, host: str, port: int, parser_factory):
        self.server = server
        self.host = host
        self.port = port
        self.parser_factory = parser_factory
        self.state = "starting"
        self.connections = 0
        self.parsers: list[LineParser] = []
        self._listener = None

    @property
    def name(self) -> str:
        return f"tcp://{self.host}:{self.port}"

    async def start_async(self) -> None:
        self._listener = await asyncio.start_server(self._serve, self.host, self.port)
        self.port = self._listener.sockets[0].getsockname()[1]
        self.state = "running"

    def stop(self) -> None:
        if self._listener is not None:
            self._listener.close()

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.connections += 1
        peer = writer.get_extra_info("peername")
        parser = self.parser_factory(f"tcp connection {self.connections} from {peer[0]}:{peer[1]}")
        self.parsers.append(parser)
        feeder = _Feeder(self.server, parser, self.server.submit)
        lines = _Lines()
        token = self.server.token
        try:
            while True:
                data = await reader.read(READ_BYTES)
                got = lines.feed(data, final=not data)
                if token is not None and got:
                    first = got.pop(0).strip()
                    if not hmac.compare_digest(first.encode(), f"#token {token}".encode()):
                        raise WavemeterError("refused: send the line '#token TOKEN' first")
                    token = None
                feeder.lines(got)
                if not data:
                    break
        except WavemeterError as exc:
            writer.write(f"error: {exc}\n".encode())
            await writer.drain()
        except (ConnectionError, asyncio.CancelledError):
            pass  # the peer went, or the service is stopping: the lines so far are in
        finally:
            self.parsers.remove(parser)
            self.server.note_lines(parser)
            writer.close()

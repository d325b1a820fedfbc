"""Line sources: standard input, a file (read to its end, or followed), a TCP port.

Each source reads text lines and turns them into :class:`RowBlock` s with its own
:class:`LineParser` (the column rules of ``wavemeter stream``), then hands them to the
server. Standard input and files are read by a thread (``os.read`` of what is there, or
:func:`wavemeter.jobs.follow_lines`); the TCP source is a listening socket the loop watches
(``add_reader``): an acquisition program connects and writes a header line and then
readings, and several may at once.
A header the calibration cannot read ends a standard-input or file source as a start-up
error would; a TCP connection gets an ``error:`` line and is closed. With a token, a TCP
connection must first send the line ``#token TOKEN``.
"""

from __future__ import annotations

import asyncio
import codecs
import hmac
import os
import socket
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

    The listening socket and each connection are plain non-blocking sockets watched by the
    loop (``loop.add_reader``): what a connection holds is read and handed on in the
    callback itself, with no stream buffer or task to wake between the bytes and the
    readings.

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
        self._listener: socket.socket | None = None
        self._open: list[_Connection] = []
        self._loop = None

    @property
    def name(self) -> str:
        return f"tcp://{self.host}:{self.port}"

    async def start_async(self) -> None:
        self._loop = asyncio.get_running_loop()
        family = socket.AF_INET6 if ":" in self.host else socket.AF_INET
        listener = socket.socket(family, socket.SOCK_STREAM)
        try:
            listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            listener.bind((self.host, self.port))
            listener.listen(100)
        except OSError:
            listener.close()
            raise
        listener.setblocking(False)
        self._listener = listener
        self.port = listener.getsockname()[1]
        self._loop.add_reader(listener.fileno(), self._accept)
        self.state = "running"

    def stop(self) -> None:
        """Stop listening; what each connection has sent so far is read, then it is closed."""
        if self._listener is not None:
            self._loop.remove_reader(self._listener.fileno())
            self._listener.close()
            self._listener = None
        for connection in list(self._open):
            connection.readable(last=True)

    def _accept(self) -> None:
        try:
            conn, peer = self._listener.accept()
        except (BlockingIOError, InterruptedError):
            return
        conn.setblocking(False)
        if conn.family in (socket.AF_INET, socket.AF_INET6):
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.connections += 1
        parser = self.parser_factory(f"tcp connection {self.connections} from {peer[0]}:{peer[1]}")
        self.parsers.append(parser)
        connection = _Connection(self, conn, parser)
        self._open.append(connection)
        self._loop.add_reader(conn.fileno(), connection.readable)


class _Connection:
    """One acquisition program's connection: bytes to lines to readings, in the loop's
    callback."""

    def __init__(self, source: TcpLineSource, conn: socket.socket, parser: LineParser):
        self.source = source
        self.conn = conn
        self.parser = parser
        self.feeder = _Feeder(source.server, parser, source.server.submit)
        self.lines = _Lines()
        self.token = source.server.token

    def readable(self, last: bool = False) -> None:
        """Read what the socket holds (``last``: all of it, then close)."""
        while True:
            try:
                data = self.conn.recv(READ_BYTES)
            except (BlockingIOError, InterruptedError):
                if last:
                    self.close()
                return
            except OSError:  # the peer went: the lines so far are in
                data = b""
            try:
                got = self.lines.feed(data, final=not data)
                if self.token is not None and got:
                    first = got.pop(0).strip()
                    if not hmac.compare_digest(first.encode(), f"#token {self.token}".encode()):
                        raise WavemeterError("refused: send the line '#token TOKEN' first")
                    self.token = None
                self.feeder.lines(got)
            except WavemeterError as exc:
                self._reply(f"error: {exc}\n".encode())
                data = b""
            except BaseException:
                self.close()  # not left watched; the loop reports the error
                raise
            if not data:
                self.close()
                return
            if not last:
                return  # once per readiness: the loop calls again while more waits

    def _reply(self, message: bytes) -> None:
        try:
            self.conn.setblocking(True)
            self.conn.settimeout(1.0)
            self.conn.sendall(message)
        except OSError:
            pass  # the peer went

    def close(self) -> None:
        source = self.source
        if self not in source._open:
            return
        source._open.remove(self)
        source._loop.remove_reader(self.conn.fileno())
        source.parsers.remove(self.parser)
        source.server.note_lines(self.parser)
        self.conn.close()

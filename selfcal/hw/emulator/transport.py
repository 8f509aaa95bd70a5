"""The terminals of the ACL controller emulator: a pseudo-terminal and TCP connections.

``Terminal`` is one terminal's line discipline (line buffer, CR/LF, backspace, Ctrl-A, XON/XOFF
and NUL ignored) with its own echo flag and question state; it hands complete lines to its
controller. ``PtyPort`` serves the pty (``os.openpty``; a client opens its slave path, optionally
through a stable symbolic link), ``TcpPort`` serves 127.0.0.1: every accepted connection is one
more terminal of the same controller.
"""

from __future__ import annotations

import os
import select
import socket
import threading
import time
import tty
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

from selfcal.errors import OutputError

__all__ = ["TerminalOwner", "Terminal", "PtyPort", "TcpPort"]


class TerminalOwner(Protocol):
    """What a terminal needs of its controller (``selfcal.hw.emulator.controller.AclController``)."""

    echo_default: bool
    received: bytearray
    terminals: list[Terminal]

    def ctrl_a(self) -> None:
        """Ctrl-A (0x01) arrived: abort."""

    def handle_line(self, sess: Terminal, line: str) -> None:
        """A complete line arrived on ``sess``."""

    def attach(self, sess: Terminal) -> None:
        """Add a terminal."""

    def detach(self, sess: Terminal) -> None:
        """Remove a closed terminal."""


class Terminal:
    """One terminal (pty or TCP connection): its own line buffer, echo flag and question state."""

    def __init__(
        self,
        controller: TerminalOwner,
        name: str,
        write: Callable[[bytes], None],
        close: Callable[[], None],
    ):
        self.controller = controller
        self.name = name
        self._write = write
        self._close = close
        self.echo = controller.echo_default
        self.buf = bytearray()
        self.question: tuple[str, int] | None = None  # (position, axis) being asked
        self.alive = True
        self._wlock = threading.Lock()

    def send(self, text: str | bytes) -> None:
        if not self.alive or not text:
            return
        data = text.encode("latin-1") if isinstance(text, str) else text
        with self._wlock:
            try:
                self._write(data)
            except OSError:
                self.close()

    def close(self) -> None:
        if self.alive:
            self.alive = False
            try:
                self._close()
            except OSError:
                pass

    def feed(self, data: bytes) -> None:
        self.controller.received += data
        for b in data:
            if b == 0x01:
                self.buf.clear()
                self.question = None
                self.controller.ctrl_a()
            elif b in (0x11, 0x13, 0x00):
                continue
            elif b in (0x0D, 0x0A):
                if b == 0x0A and self._last == 0x0D:
                    self._last = b
                    continue
                line = self.buf.decode("latin-1")
                self.buf.clear()
                self.controller.handle_line(self, line)
            elif b == 0x08 or b == 0x7F:
                if self.buf:
                    self.buf.pop()
            else:
                self.buf.append(b)
            self._last = b

    _last = 0


class PtyPort:
    """The controller's pseudo-terminal: a raw pty whose slave path (``path``) a client opens.

    Args:
        link: a path made a symbolic link to the pty on ``open`` (replacing an earlier link),
            removed by ``remove_link``; ``None``: no link.
    """

    def __init__(self, link: Path | None = None):
        self.link = link
        self.path: str | None = None
        self._master_fd: int | None = None
        self._slave_fd: int | None = None

    def open(self) -> str:
        """Open the pty (and the link); returns its path."""
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo/line editing by the kernel before a client configures it
        os.set_blocking(master, False)
        self._master_fd, self._slave_fd = master, slave
        self.path = os.ttyname(slave)
        if self.link is not None:
            self._make_link()
        return self.path

    def _make_link(self) -> None:
        link = self.link
        assert link is not None and self.path is not None
        if link.exists() and not link.is_symlink():
            raise OutputError(
                f"pty_link {link} exists and is not a symbolic link; not replacing it"
            )
        link.parent.mkdir(parents=True, exist_ok=True)
        tmp = link.with_name(f".{link.name}.{os.getpid()}.tmp")
        if tmp.is_symlink():
            tmp.unlink()
        os.symlink(self.path, tmp)
        os.replace(tmp, link)

    def remove_link(self) -> None:
        """Remove the link if it still points at this pty."""
        link = self.link
        if link is not None and link.is_symlink() and os.readlink(link) == self.path:
            try:
                link.unlink()
            except OSError:
                pass

    def write(self, data: bytes) -> None:
        fd = self._master_fd
        if fd is None:
            raise OutputError("pty closed")
        deadline = time.monotonic() + 1.0
        view = memoryview(data)
        while view:
            try:
                n = os.write(fd, view)
                view = view[n:]
            except BlockingIOError:
                if time.monotonic() > deadline:
                    return  # nobody reads: drop, as a serial line would
                time.sleep(0.001)

    def close(self) -> None:
        """Close master and slave: the pty's path disappears."""
        for attr in ("_master_fd", "_slave_fd"):
            fd = getattr(self, attr)
            setattr(self, attr, None)
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass

    def serve(self, sess: Terminal, stop: threading.Event) -> None:
        """Feed what the client writes to ``sess`` until ``stop`` or the terminal closes."""
        while not stop.is_set() and sess.alive:
            fd = self._master_fd
            if fd is None:
                return
            try:
                r, _, _ = select.select([fd], [], [], 0.05)
                if not r:
                    continue
                data = os.read(fd, 4096)
            except (OSError, ValueError):
                if sess.alive and not stop.is_set():
                    time.sleep(0.01)  # EIO while no client holds the slave: keep serving
                    continue
                return
            if data:
                sess.feed(data)


class TcpPort:
    """TCP terminals on 127.0.0.1: every accepted connection is a terminal of ``controller``.

    Args:
        controller: the terminals' controller.
        spawn: starts ``fn(*args)`` on a new thread (the emulator's, so it joins them on stop).
        stop: set when the emulator stops.
    """

    def __init__(
        self,
        controller: TerminalOwner,
        spawn: Callable[..., Any],
        stop: threading.Event,
    ):
        self.controller = controller
        self._spawn = spawn
        self._stop = stop
        self._server: socket.socket | None = None
        self.address: tuple[str, int] | None = None

    def open(self, port: int) -> tuple[str, int]:
        """Listen on 127.0.0.1:``port`` (0 = any free port); returns the address."""
        srv = socket.create_server(("127.0.0.1", int(port)))
        srv.settimeout(0.05)
        self._server = srv
        self.address = srv.getsockname()[:2]
        return self.address

    def close(self) -> None:
        """Stop listening (open connections are the controller's terminals)."""
        if self._server is not None:
            try:
                self._server.close()
            except OSError:
                pass

    def accept_loop(self) -> None:
        srv = self._server
        assert srv is not None
        while not self._stop.is_set():
            try:
                conn, _ = srv.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            conn.settimeout(0.05)

            def close(c: socket.socket = conn) -> None:
                try:
                    c.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
                c.close()

            sess = Terminal(
                self.controller, f"tcp{len(self.controller.terminals)}", conn.sendall, close
            )
            self.controller.attach(sess)
            self._spawn(self._connection_loop, sess, conn)

    def _connection_loop(self, sess: Terminal, conn: socket.socket) -> None:
        while not self._stop.is_set() and sess.alive:
            try:
                data = conn.recv(4096)
            except TimeoutError:
                continue
            except OSError:
                break
            if not data:
                break
            sess.feed(data)
        sess.close()
        self.controller.detach(sess)

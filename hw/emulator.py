"""An ACL controller emulator, so the whole hardware path runs without a SCORBOT.

``AclEmulator`` speaks the ACL dialogue of ``shared/hardware/acl-notes.md`` on a pseudo-terminal
(``os.openpty``; point the adapter at ``pty_path``) and on a TCP port on 127.0.0.1 (``url`` =
``socket://127.0.0.1:<port>``). Both are terminals of the same controller: one arm, one state.

What it answers: the prompt (``>`` on its own line, or after the last value with
``prompt_same_line=True``), ``ECHO``/``NOECHO`` (echo on by default), ``VER``, ``CON``/``COFF``,
``HOME`` (blocking: ``WAIT!! HOMING...`` then ``HOMING COMPLETE (ROBOT)`` and the prompt),
``SPEED n``, ``SHOW SPEED``, ``DEFP pos``, ``SETPV pos axis value`` and the interactive
``SETPV pos`` (``1 -- [0] >`` questions), ``HERE pos``, ``MOVE pos [duration]`` (queued, returns at
once, takes time; ``PRINT MFLAG`` is the bit mask of moving axes meanwhile), ``LISTPV POSITION`` /
``LISTPV pos``, Ctrl-A (0x01) and ``A`` (abort), ``CLRBUF``; ``*** OUT OF RANGE axis n`` for targets
outside the backend's limits, ``AXIS DISABLED`` for motion while control is off,
``NO POSITION ASSIGNED TO POINT pos`` for incomplete positions.

Faults (``faults=`` or ``inject_fault``): ``timeout`` (no reply at all; the command still takes
effect unless ``execute=False``), ``garble`` (bit errors: every third reply byte gets its top bit
flipped), ``drop`` (every second reply byte is lost), ``impact`` (during the triggering MOVE, at
``at_fraction`` of it: the arm stops, ``*** IMPACT PROTECTION axis n`` is printed asynchronously,
control goes off), ``disconnect`` (``after_s`` after the triggering command every connection is
closed; the pty disappears), ``home_failure`` (``*** HOME FAILURE AXIS n`` instead of homing).

The arm itself is an ``EmulatorBackend``: the emulator tells it where the arm came to rest and asks
it for the stereo pair seen there. After every rest (and at start) the pair is written as
``<frames_dir>/%06d_left.png`` / ``%06d_right.png`` -- *before* ``PRINT MFLAG`` reports 0 -- which
``hw.cameras`` reads through ``cv2.VideoCapture`` (``cv2.CAP_IMAGES``, ``"latest"`` mode).
"""

from __future__ import annotations

import json
import os
import re
import select
import socket
import tempfile
import threading
import time
import tty
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import cv2
import numpy as np

from calib.errors import InputError
from calib.kinematics import fk_dh
from calib.robot import StereoPair
from calib.robot_def import RobotDef, load_robot
from hw.encoders import EncoderTable

__all__ = [
    "EmulatorBackend",
    "KinematicBackend",
    "Fault",
    "FAULT_KINDS",
    "AclEmulator",
]

FAULT_KINDS = ("timeout", "garble", "drop", "impact", "disconnect", "home_failure")
_FRAME_FILE = re.compile(r"\d{6}_(left|right)\.png")


@runtime_checkable
class EmulatorBackend(Protocol):
    """The arm behind the emulated controller.

    Attributes:
        model_name: robot model name (``models/robots/<name>.toml``), used for LISTPV's Cartesian
            line when the backend has no ``robot`` attribute.
        limits_deg: (n, 2) joint ranges (deg) the controller enforces (``*** OUT OF RANGE``).
    """

    model_name: str
    limits_deg: np.ndarray
    # optional: ``robot`` (a ``RobotDef``, for LISTPV's Cartesian line) and ``encoders`` (an
    # ``EncoderTable``: the emulator's default table when it is given none)

    def set_joints_deg(self, joints_deg: np.ndarray) -> np.ndarray | None:
        """The arm has come to rest at ``joints_deg`` (n,) (deg, as commanded in encoder counts).
        Return the joint angles the encoders actually read there (e.g. with servo error), or
        ``None`` for "as commanded"."""

    def capture(self) -> StereoPair:
        """The stereo pair (RGB uint8) seen at the current posture."""


class KinematicBackend:
    """Pure-kinematic arm: remembers the posture, renders nothing (blank images).

    Args:
        robot: model name or ``RobotDef`` (limits and the Cartesian line of LISTPV).
        image_size: (width, height) of the blank images.
        limits_deg: override of the (n, 2) joint ranges (deg), e.g. tighter than the model's.
    """

    def __init__(
        self,
        robot: str | RobotDef = "er4u-vendor",
        image_size: tuple[int, int] = (640, 480),
        limits_deg: np.ndarray | None = None,
    ):
        self.robot = load_robot(robot) if isinstance(robot, str) else robot
        self.model_name = self.robot.name
        lim = np.degrees(self.robot.limits) if limits_deg is None else limits_deg
        self.limits_deg = np.asarray(lim, dtype=float).reshape(self.robot.n, 2)
        self.image_size = (int(image_size[0]), int(image_size[1]))
        self.joints_deg = np.degrees(self.robot.home)
        self.rests = 0

    def set_joints_deg(self, joints_deg: np.ndarray) -> np.ndarray | None:
        self.joints_deg = np.asarray(joints_deg, dtype=float).copy()
        self.rests += 1
        return None

    def capture(self) -> StereoPair:
        w, h = self.image_size
        blank = np.zeros((h, w, 3), dtype=np.uint8)
        return StereoPair(blank, blank.copy(), {"joints_deg": self.joints_deg.tolist()})


@dataclass
class Fault:
    """One injected fault (see the module docstring for the kinds).

    Attributes:
        kind: one of ``FAULT_KINDS``.
        on: command prefix that triggers it (case-insensitive, e.g. ``"MOVE"``, ``"PRINT MFLAG"``,
            ``"LISTPV"``); ``None``: the next command.
        count: how many times it fires; ``-1``: every time.
        axis: axis named by ``impact`` / ``home_failure``.
        at_fraction: ``impact``: fraction of the motion after which the arm hits.
        after_s: ``disconnect``: delay after the triggering command.
        execute: ``timeout``: whether the unanswered command still takes effect.
        skip: let this many matching commands pass before the fault fires (e.g. ``on="MOVE",
            skip=5``: the sixth MOVE).
    """

    kind: str
    on: str | None = None
    count: int = 1
    axis: int = 2
    at_fraction: float = 0.4
    after_s: float = 0.05
    execute: bool = True
    skip: int = 0

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise InputError(f"unknown fault kind {self.kind!r}; known: {', '.join(FAULT_KINDS)}")
        if self.count == 0 or self.count < -1:
            raise InputError(f"fault count must be positive or -1 (always), got {self.count}")
        if self.skip < 0:
            raise InputError(f"fault skip must be >= 0, got {self.skip}")
        if not 0.0 <= self.at_fraction <= 1.0:
            raise InputError(f"at_fraction must be in [0, 1], got {self.at_fraction}")

    def matches(self, command: str) -> bool:
        return self.on is None or command.startswith(" ".join(self.on.upper().split()))


@dataclass
class _Segment:
    start: np.ndarray
    target: np.ndarray
    t0: float
    t1: float
    kind: str  # "move" | "home"
    session: _Session | None = None
    impact: Fault | None = None

    def counts_at(self, now: float) -> np.ndarray:
        if self.t1 <= self.t0:
            return self.target.copy()
        s = min(max((now - self.t0) / (self.t1 - self.t0), 0.0), 1.0)
        return np.rint(self.start + (self.target - self.start) * s).astype(np.int64)


class _Session:
    """One terminal (pty or TCP connection): its own line buffer, echo flag and question state."""

    def __init__(
        self, emu: AclEmulator, name: str, write: Callable[[bytes], None], close: Callable[[], None]
    ):
        self.emu = emu
        self.name = name
        self._write = write
        self._close = close
        self.echo = emu.echo_default
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
        self.emu.received += data
        for b in data:
            if b == 0x01:
                self.buf.clear()
                self.question = None
                self.emu._ctrl_a()
            elif b in (0x11, 0x13, 0x00):
                continue
            elif b in (0x0D, 0x0A):
                if b == 0x0A and self._last == 0x0D:
                    self._last = b
                    continue
                line = self.buf.decode("latin-1")
                self.buf.clear()
                self.emu._handle_line(self, line)
            elif b == 0x08 or b == 0x7F:
                if self.buf:
                    self.buf.pop()
            else:
                self.buf.append(b)
            self._last = b

    _last = 0


class AclEmulator:
    """An emulated SCORBOT controller (Controller-A style ACL, DIRECT mode).

    Args:
        backend: the arm (default ``KinematicBackend()``).
        echo: initial ECHO state of each terminal.
        line_end: ``"\\r\\n"`` or ``"\\r"``.
        move_speed_deg_s: joint speed (deg/s) of the slowest-finishing joint at the default SPEED 50
            (scaled with SPEED n).
        faults: initial faults.
        prompt_same_line: print the prompt after the last reply value (``R:-3 >``).
        pty: serve a pseudo-terminal.
        tcp_port: serve TCP on 127.0.0.1:tcp_port (0 = any free port; ``None`` = no TCP).
        frames_dir: where stereo frames go (default: a fresh temporary directory).
        write_frames: write a stereo pair after every rest.
        home_duration_s: duration of HOME (default: a move to the home posture).
        encoders: the encoder table (default: the backend's ``encoders`` attribute if it has one,
            else ``EncoderTable.er4u()``).
        control_on: initial CON state.
        xon_in_replies: sprinkle XON (0x11) bytes into replies, as Controller-A may.
        pty_link: a path made a symbolic link to the pty (replaced on every start, removed on
            stop and on a disconnect), so a config can name a port that survives restarts.

    Frames left in ``frames_dir`` by an earlier run (``NNNNNN_left.png`` / ``_right.png``) are
    deleted at start: the cameras read the newest index, which would otherwise be a stale one.
    """

    def __init__(
        self,
        backend: EmulatorBackend | None = None,
        *,
        echo: bool = True,
        line_end: str = "\r\n",
        move_speed_deg_s: float = 60.0,
        faults: Iterable[Fault | dict] = (),
        prompt_same_line: bool = False,
        pty: bool = True,
        tcp_port: int | None = 0,
        frames_dir: str | Path | None = None,
        write_frames: bool = True,
        home_duration_s: float | None = None,
        encoders: EncoderTable | None = None,
        control_on: bool = True,
        xon_in_replies: bool = False,
        pty_link: str | Path | None = None,
    ):
        if line_end not in ("\r\n", "\r", "\n"):
            raise InputError(f"line_end must be '\\r\\n', '\\r' or '\\n', got {line_end!r}")
        if move_speed_deg_s <= 0:
            raise InputError(f"move_speed_deg_s must be positive, got {move_speed_deg_s}")
        self.backend: EmulatorBackend = backend if backend is not None else KinematicBackend()
        self.encoders = encoders or getattr(self.backend, "encoders", None) or EncoderTable.er4u()
        if not isinstance(self.encoders, EncoderTable):
            raise TypeError(f"encoders must be an EncoderTable, got {type(self.encoders).__name__}")
        self.limits_deg = np.asarray(self.backend.limits_deg, dtype=float)
        if self.limits_deg.shape != (self.encoders.n, 2):
            raise InputError(
                f"backend limits_deg has shape {self.limits_deg.shape}, the encoder table has "
                f"{self.encoders.n} axes"
            )
        self.n = self.encoders.n
        robot = getattr(self.backend, "robot", None)
        if not isinstance(robot, RobotDef):
            try:
                robot = load_robot(self.backend.model_name)
            except Exception:  # noqa: BLE001 - Cartesian line is optional
                robot = None
        self.robot = robot if robot is not None and robot.n == self.n else None
        self.echo_default = bool(echo)
        self.line_end = line_end
        self.move_speed_deg_s = float(move_speed_deg_s)
        self.prompt_same_line = bool(prompt_same_line)
        self.home_duration_s = home_duration_s
        self.xon_in_replies = bool(xon_in_replies)
        self.write_frames = bool(write_frames)
        self._tmpdir = None
        if frames_dir is None and write_frames:
            self._tmpdir = tempfile.TemporaryDirectory(prefix="acl-emu-frames-")
            frames_dir = self._tmpdir.name
        self.frames_dir = Path(frames_dir) if frames_dir is not None else None
        if self.frames_dir is not None:
            self.frames_dir.mkdir(parents=True, exist_ok=True)
        self._want_pty = bool(pty)
        self.pty_link = Path(pty_link) if pty_link is not None else None
        if self.pty_link is not None and not self._want_pty:
            raise InputError("pty_link needs pty=True")
        self._want_tcp_port = tcp_port

        self._lock = threading.RLock()
        self._counts = self.encoders.home_counts.copy()
        self._segment: _Segment | None = None
        self._queue: deque[tuple[np.ndarray, float | None, Fault | None]] = deque()
        self._positions: dict[str, list[int | None]] = {}
        self._control = bool(control_on)
        self._speed = 50
        self._homed = False
        self._faults: list[Fault] = [f if isinstance(f, Fault) else Fault(**f) for f in faults]
        self._scheduled: list[tuple[float, Callable[[], None]]] = []
        self._sessions: list[_Session] = []
        self._frame_index = 0
        self.commands: list[str] = []
        self.received = bytearray()
        self.disconnected = False

        self.pty_path: str | None = None
        self.tcp_address: tuple[str, int] | None = None
        self._master_fd: int | None = None
        self._slave_fd: int | None = None
        self._server: socket.socket | None = None
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._started = False

    # -- lifecycle -----------------------------------------------------------------------------

    def start(self) -> AclEmulator:
        """Open the pty / TCP port, put the arm at rest at the encoder home, start serving."""
        if self._started:
            return self
        self._started = True
        if self.frames_dir is not None and self._tmpdir is None:
            for f in self.frames_dir.iterdir():
                if _FRAME_FILE.fullmatch(f.name):
                    f.unlink()
        with self._lock:
            self._arrive()
        if self._want_pty:
            master, slave = os.openpty()
            tty.setraw(slave)  # no echo/line editing by the kernel before a client configures it
            os.set_blocking(master, False)
            self._master_fd, self._slave_fd = master, slave
            self.pty_path = os.ttyname(slave)
            if self.pty_link is not None:
                self._make_link()
            sess = _Session(self, "pty", self._pty_write, self._pty_close)
            self._sessions.append(sess)
            self._spawn(self._pty_loop, sess)
        if self._want_tcp_port is not None:
            srv = socket.create_server(("127.0.0.1", int(self._want_tcp_port)))
            srv.settimeout(0.05)
            self._server = srv
            self.tcp_address = srv.getsockname()[:2]
            self._spawn(self._accept_loop)
        self._spawn(self._tick_loop)
        return self

    def _make_link(self) -> None:
        link = self.pty_link
        assert link is not None and self.pty_path is not None
        if link.exists() and not link.is_symlink():
            raise FileExistsError(
                f"pty_link {link} exists and is not a symbolic link; not replacing it"
            )
        link.parent.mkdir(parents=True, exist_ok=True)
        tmp = link.with_name(f".{link.name}.{os.getpid()}.tmp")
        if tmp.is_symlink():
            tmp.unlink()
        os.symlink(self.pty_path, tmp)
        os.replace(tmp, link)

    def _remove_link(self) -> None:
        link = self.pty_link
        if link is not None and link.is_symlink() and os.readlink(link) == self.pty_path:
            try:
                link.unlink()
            except OSError:
                pass

    def stop(self) -> None:
        """Stop serving and close everything (idempotent)."""
        self._stop.set()
        self._remove_link()
        for s in list(self._sessions):
            s.close()
        if self._server is not None:
            try:
                self._server.close()
            except OSError:
                pass
        for t in self._threads:
            if t is not threading.current_thread():
                t.join(timeout=2.0)
        self._threads.clear()
        if self._tmpdir is not None:
            self._tmpdir.cleanup()
            self._tmpdir = None

    def __enter__(self) -> AclEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _spawn(self, fn: Callable[..., None], *args: Any) -> None:
        t = threading.Thread(target=fn, args=args, daemon=True, name=f"acl-emu-{fn.__name__}")
        self._threads.append(t)
        t.start()

    @property
    def url(self) -> str | None:
        """``socket://127.0.0.1:<port>`` of the TCP terminal, if served."""
        if self.tcp_address is None:
            return None
        return f"socket://{self.tcp_address[0]}:{self.tcp_address[1]}"

    @property
    def camera_sources(self) -> tuple[str, str]:
        """Image-sequence patterns (left, right) for ``hw.cameras`` / ``[robot.hardware] cameras``."""
        if self.frames_dir is None:
            raise RuntimeError("the emulator writes no frames (write_frames=False, no frames_dir)")
        return (str(self.frames_dir / "%06d_left.png"), str(self.frames_dir / "%06d_right.png"))

    @property
    def port(self) -> str | None:
        """The port a client should name: ``pty_link`` if set, else the pty path, else the URL."""
        if self.pty_link is not None and self.pty_path is not None:
            return str(self.pty_link)
        return self.pty_path or self.url

    def hardware_snippet(self, port: str | None = None) -> str:
        """The ``[robot.hardware]`` TOML table that points a scenario (or ``selfcal hw --config``)
        at this emulator: ``port`` (default ``self.port``), ``cameras`` (the frame sequences) and
        the emulator's encoder table under ``[robot.hardware.options.encoders]``, so that the
        adapter converts counts exactly as the emulated controller does."""
        port = port or self.port
        if port is None:
            raise RuntimeError("the emulator is not started (no port yet)")
        enc = self.encoders.to_config()
        lines = [
            f'# scenario: [robot] backend = "hardware", model = "{self.backend.model_name}"',
            "[robot.hardware]",
            f"port = {json.dumps(port)}",
        ]
        if self.frames_dir is not None:
            left, right = self.camera_sources
            lines.append(f"cameras = [{json.dumps(left)}, {json.dumps(right)}]")
        lines += ["", "[robot.hardware.options.encoders]"]
        for key in ("counts_per_deg", "home_deg", "home_counts", "differential"):
            val = enc[key]
            lines.append(f"{key} = {json.dumps(val) if val is not False else 'false'}")
        return "\n".join(lines) + "\n"

    # -- transports ----------------------------------------------------------------------------

    def _pty_write(self, data: bytes) -> None:
        fd = self._master_fd
        if fd is None:
            raise OSError("pty closed")
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

    def _pty_close(self) -> None:
        for attr in ("_master_fd", "_slave_fd"):
            fd = getattr(self, attr)
            setattr(self, attr, None)
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass

    def _pty_loop(self, sess: _Session) -> None:
        while not self._stop.is_set() and sess.alive:
            fd = self._master_fd
            if fd is None:
                return
            try:
                r, _, _ = select.select([fd], [], [], 0.05)
                if not r:
                    continue
                data = os.read(fd, 4096)
            except (OSError, ValueError):
                if sess.alive and not self._stop.is_set():
                    time.sleep(0.01)  # EIO while no client holds the slave: keep serving
                    continue
                return
            if data:
                sess.feed(data)

    def _accept_loop(self) -> None:
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

            sess = _Session(self, f"tcp{len(self._sessions)}", conn.sendall, close)
            with self._lock:
                self._sessions.append(sess)
            self._spawn(self._tcp_loop, sess, conn)

    def _tcp_loop(self, sess: _Session, conn: socket.socket) -> None:
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
        with self._lock:
            if sess in self._sessions:
                self._sessions.remove(sess)

    def _tick_loop(self) -> None:
        while not self._stop.wait(0.003):
            with self._lock:
                self._advance(time.monotonic())

    # -- public state & control ----------------------------------------------------------------

    def inject_fault(self, kind: str | Fault, **kwargs: Any) -> Fault:
        """Add a fault (``Fault`` or kind + ``Fault`` fields); returns it."""
        f = kind if isinstance(kind, Fault) else Fault(kind, **kwargs)
        with self._lock:
            self._faults.append(f)
        return f

    def clear_faults(self) -> None:
        with self._lock:
            self._faults.clear()

    @property
    def faults(self) -> list[Fault]:
        with self._lock:
            return list(self._faults)

    def counts(self) -> np.ndarray:
        """Current encoder counts (n,)."""
        with self._lock:
            self._advance(time.monotonic())
            return self._current_counts(time.monotonic())

    def joints_deg(self) -> np.ndarray:
        """Current joint angles (deg) from the counts."""
        return self.encoders.to_degrees(self.counts())

    @property
    def moving(self) -> bool:
        with self._lock:
            self._advance(time.monotonic())
            return self._segment is not None

    @property
    def control_on(self) -> bool:
        return self._control

    @property
    def frames_written(self) -> int:
        return self._frame_index

    def wait_until_still(self, timeout_s: float = 5.0) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if not self.moving:
                return True
            time.sleep(0.005)
        return False

    # -- motion model --------------------------------------------------------------------------

    def _current_counts(self, now: float) -> np.ndarray:
        if self._segment is not None:
            return self._segment.counts_at(now)
        return self._counts.copy()

    def _duration(self, start: np.ndarray, target: np.ndarray) -> float:
        dq = np.abs(self.encoders.to_degrees(target) - self.encoders.to_degrees(start))
        speed = self.move_speed_deg_s * self._speed / 50.0
        return float(np.max(dq) / speed) if dq.size else 0.0

    def _start_segment(
        self,
        target: np.ndarray,
        duration: float | None,
        kind: str,
        t0: float,
        session: _Session | None = None,
        impact: Fault | None = None,
    ) -> None:
        start = self._counts.copy()
        dur = self._duration(start, target) if duration is None else float(duration)
        seg = _Segment(start, target.astype(np.int64), t0, t0 + dur, kind, session, impact)
        self._segment = seg
        if impact is not None:
            t_hit = seg.t0 + impact.at_fraction * (seg.t1 - seg.t0)
            self._scheduled.append((t_hit, lambda: self._impact(seg, impact.axis, t_hit)))

    def _advance(self, now: float) -> None:
        """Bring the controller to time ``now``: scheduled events (impact, disconnect, ...) and
        segment ends are processed in time order, each at its own time, so a late tick of the
        clock thread changes nothing."""
        while True:
            seg_end = self._segment.t1 if self._segment is not None else float("inf")
            due = [ev for ev in self._scheduled if ev[0] <= now]
            first = min(due, key=lambda ev: ev[0]) if due else None
            if first is not None and first[0] <= seg_end:
                self._scheduled.remove(first)
                first[1]()
                continue
            if self._segment is not None and now >= seg_end:
                self._finish_segment()
                continue
            return

    def _finish_segment(self) -> None:
        seg = self._segment
        assert seg is not None
        self._segment = None
        self._counts = seg.target.copy()
        self._arrive()
        if seg.kind == "home":
            self._homed = True
            if seg.session is not None:
                seg.session.send(self._format(["HOMING COMPLETE (ROBOT)"]))
        if self._queue:
            target, dur, impact = self._queue.popleft()
            self._start_segment(target, dur, "move", seg.t1, impact=impact)

    def _arrive(self) -> None:
        """The arm is at rest at ``self._counts``: tell the backend, write the stereo frame."""
        q = self.encoders.to_degrees(self._counts)
        reported = self.backend.set_joints_deg(q)
        if reported is not None:
            self._counts = self.encoders.to_counts(
                np.asarray(reported, dtype=float).reshape(self.n)
            )
        if self.write_frames and self.frames_dir is not None:
            pair = self.backend.capture()
            self._write_pair(pair)

    def _write_pair(self, pair: StereoPair) -> None:
        i = self._frame_index
        for side, img in (("right", pair.right), ("left", pair.left)):  # right first: see cameras
            img = np.asarray(img)
            bgr = cv2.cvtColor(img, cv2.COLOR_RGB2BGR) if img.ndim == 3 else img
            final = self.frames_dir / f"{i:06d}_{side}.png"
            tmp = self.frames_dir / f".tmp_{side}.png"
            if not cv2.imwrite(str(tmp), bgr):
                raise OSError(f"cannot write {tmp}")
            os.replace(tmp, final)
        self._frame_index = i + 1

    def _stop_motion(self, at: float | None = None) -> str | None:
        """Stop wherever the arm is (at time ``at``, default now); returns the kind of the
        interrupted segment."""
        now = time.monotonic() if at is None else at
        kind = None
        if self._segment is not None:
            kind = self._segment.kind
            self._counts = self._segment.counts_at(now)
            self._segment = None
            self._arrive()
        self._queue.clear()
        return kind

    def _ctrl_a(self) -> None:
        with self._lock:
            self.commands.append("^A")
            self._advance(time.monotonic())
            self._stop_motion()

    def _impact(self, seg: _Segment, axis: int, t_hit: float) -> None:
        if self._segment is not seg:
            return  # that motion already ended or was aborted
        self._stop_motion(at=t_hit)
        self._control = False
        self._broadcast(f"{self.line_end}*** IMPACT PROTECTION axis {axis}{self.line_end}")

    def _broadcast(self, text: str) -> None:
        for s in list(self._sessions):
            s.send(text)

    def _disconnect_all(self) -> None:
        self.disconnected = True
        self._remove_link()
        for s in list(self._sessions):
            s.close()  # the pty (master and slave) is closed: its path disappears

    # -- the dialogue --------------------------------------------------------------------------

    def _with_prompt(self, body: str) -> str:
        """Reply body (lines with their line ends) followed by the prompt."""
        xon = "\x11" if self.xon_in_replies else ""
        le = self.line_end
        if self.prompt_same_line and body.endswith(le) and body.strip():
            return body[: -len(le)] + xon + " >"
        return body + xon + ">"

    def _format(self, lines: Sequence[str]) -> str:
        return self._with_prompt("".join(line + self.line_end for line in lines))

    def _take_fault(self, command: str) -> Fault | None:
        for f in self._faults:
            if f.matches(command):
                if f.skip > 0:
                    f.skip -= 1
                    continue
                if f.count > 0:
                    f.count -= 1
                    if f.count == 0:
                        self._faults.remove(f)
                return f
        return None

    @staticmethod
    def _garble(text: str) -> str:
        b = bytearray(text.encode("latin-1"))
        for i in range(1, len(b), 3):
            b[i] ^= 0x80
        return b.decode("latin-1")

    @staticmethod
    def _drop(text: str) -> str:
        return text[::2]

    def _handle_line(self, sess: _Session, line: str) -> None:
        with self._lock:
            now = time.monotonic()
            self._advance(now)
            cmd = " ".join(line.upper().split())
            echo = (line.strip() + self.line_end) if sess.echo else ""
            if sess.question is not None:
                self.commands.append(f"? {cmd}")
                sess.send(echo + self._answer(sess, cmd))
                return
            self.commands.append(cmd)
            fault = self._take_fault(cmd) if cmd else None
            if fault is not None and fault.kind == "timeout" and not fault.execute:
                return
            out_lines, tail = self._execute(sess, cmd, fault, now)
            body = "".join(x + self.line_end for x in out_lines)
            if fault is not None and fault.kind == "garble":
                body = self._garble(body)
            elif fault is not None and fault.kind == "drop":
                body = self._drop(body)
            if fault is not None and fault.kind == "timeout":
                if self._segment is not None and self._segment.session is sess:
                    self._segment.session = None  # HOME: no completion message either
                return
            if fault is not None and fault.kind == "disconnect":
                self._scheduled.append((now + fault.after_s, self._disconnect_all))
            if tail == "prompt":
                text = self._with_prompt(body)
            else:
                text = body + tail  # a question, or nothing (HOME completes later)
            sess.send(echo + text)

    def _answer(self, sess: _Session, cmd: str) -> str:
        pos, axis = sess.question  # type: ignore[misc]
        vals = self._positions[pos]
        if not cmd:  # an empty answer keeps the value shown in brackets
            vals[axis - 1] = 0 if vals[axis - 1] is None else vals[axis - 1]
        else:
            try:
                vals[axis - 1] = int(cmd)
            except ValueError:
                sess.question = None
                return self._format(["BAD POINT COORDINATE"])
        if axis < self.n:
            sess.question = (pos, axis + 1)
            return self._question(pos, axis + 1)
        sess.question = None
        return self._format([])

    def _question(self, pos: str, axis: int) -> str:
        cur = self._positions[pos][axis - 1]
        return f"{axis} -- [{0 if cur is None else cur}] >"

    def _listpv_lines(self, name: str, counts: np.ndarray) -> list[str]:
        lines = [f"Position {name}", "  ".join(f"{a + 1}:{int(c)}" for a, c in enumerate(counts))]
        if self.robot is not None and self.n >= 5:
            q = self.encoders.to_degrees(counts)
            p = fk_dh(self.robot, np.radians(q))[0, -1, :3, 3] * 1e4  # tenths of a mm
            pitch, roll = float(np.sum(q[1:4])) * 10, float(q[4]) * 10
            vals = [*(int(round(v)) for v in p), int(round(pitch)), int(round(roll))]
            lines.append("  ".join(f"{k}:{v}" for k, v in zip("XYZPR", vals, strict=True)))
        return lines

    def _out_of_range(self, counts: np.ndarray) -> int | None:
        q = self.encoders.to_degrees(counts)
        tol = self.encoders.resolution_deg
        for j in range(self.n):
            lo, hi = self.limits_deg[j]
            if q[j] < lo - tol[j] or q[j] > hi + tol[j]:
                return j + 1
        return None

    def _execute(
        self, sess: _Session, cmd: str, fault: Fault | None, now: float
    ) -> tuple[list[str], str]:
        """Run one command; returns (reply lines, tail) with tail ``"prompt"``, a question text,
        or ``""`` (no prompt yet)."""
        tok = cmd.split()
        if not tok:
            return [], "prompt"
        op, args = tok[0], tok[1:]
        if op == "VER":
            return [
                "ESHED ROBOTEC",
                "VERSION: 1.42 (scorbot-selfcal ACL emulator)",
                "DATE : 21/07/91",
            ], "prompt"
        if op == "ECHO":
            sess.echo = True
            return [], "prompt"
        if op == "NOECHO":
            sess.echo = False
            return [], "prompt"
        if op == "CON":
            self._control = True
            return ["CONTROL ENABLED"], "prompt"
        if op == "COFF":
            self._stop_motion()
            self._control = False
            return ["CONTROL DISABLED"], "prompt"
        if op == "A" and not args:
            self._stop_motion()
            return [], "prompt"
        if op == "CLRBUF":
            self._queue.clear()
            return [], "prompt"
        if op == "SPEED" and len(args) == 1:
            try:
                v = int(args[0])
            except ValueError:
                v = -1
            if not 1 <= v <= 100:
                return ["BAD SPEED VALUE (1..100)"], "prompt"
            self._speed = v
            return [], "prompt"
        if op == "SHOW" and args == ["SPEED"]:
            return [f"GROUP A SPEED IS: {self._speed}", "O.K."], "prompt"
        if op == "DEFP" and len(args) == 1:
            self._positions.setdefault(args[0], [None] * self.n)
            return [], "prompt"
        if op == "HERE" and len(args) == 1:
            self._positions[args[0]] = [int(c) for c in self._current_counts(now)]
            return [], "prompt"
        if op == "SETPV" and len(args) in (1, 3):
            pos = args[0]
            if pos not in self._positions:
                return [f"NO POSITION ASSIGNED TO POINT {pos}"], "prompt"
            if len(args) == 1:
                sess.question = (pos, 1)
                return [], self._question(pos, 1)
            try:
                axis, value = int(args[1]), int(args[2])
            except ValueError:
                return ["BAD POINT COORDINATE"], "prompt"
            if not 1 <= axis <= self.n:
                return ["BAD POINT COORDINATE"], "prompt"
            self._positions[pos][axis - 1] = value
            return [], "prompt"
        if op == "LISTPV" and len(args) == 1:
            name = args[0]
            if name == "POSITION":
                return self._listpv_lines("POSITION", self._current_counts(now)), "prompt"
            vals = self._positions.get(name)
            if vals is None or any(v is None for v in vals):
                return [f"NO POSITION ASSIGNED TO POINT {name}"], "prompt"
            return self._listpv_lines(name, np.array(vals, dtype=np.int64)), "prompt"
        if op == "PRINT" and args == ["MFLAG"]:
            mask = 0
            if self._segment is not None:
                moving = self._segment.target != self._segment.start
                mask = int(sum(1 << j for j in range(self.n) if moving[j]))
                if mask == 0 and self._segment.t1 > now:
                    mask = (1 << self.n) - 1
            return [str(mask)], "prompt"
        if op == "MOVE" and len(args) in (1, 2):
            if not self._control:
                return ["AXIS DISABLED"], "prompt"
            name = args[0]
            vals = self._positions.get(name)
            if vals is None or any(v is None for v in vals):
                return [f"NO POSITION ASSIGNED TO POINT {name}"], "prompt"
            target = np.array(vals, dtype=np.int64)
            bad = self._out_of_range(target)
            if bad is not None:
                return [f"*** OUT OF RANGE axis {bad}"], "prompt"
            dur = None
            if len(args) == 2:
                try:
                    dur = int(args[1]) / 100.0
                except ValueError:
                    return [f"BAD DURATION {args[1]}"], "prompt"
            impact = fault if fault is not None and fault.kind == "impact" else None
            if self._segment is None:
                self._start_segment(target, dur, "move", now, impact=impact)
            else:
                self._queue.append((target, dur, impact))
            return [], "prompt"
        if op == "HOME" and not args:
            if not self._control:
                return ["AXIS DISABLED"], "prompt"
            self._stop_motion()
            if fault is not None and fault.kind == "home_failure":
                self._control = False
                axis = fault.axis
                self._scheduled.append(
                    (now + 0.02, lambda: sess.send(self._format([f"*** HOME FAILURE AXIS {axis}"])))
                )
                return ["WAIT!! HOMING..."], ""
            target = self.encoders.home_counts.copy()
            self._start_segment(target, self.home_duration_s, "home", now, session=sess)
            return ["WAIT!! HOMING..."], ""
        return [f"UNKNOWN COMMAND {cmd}"], "prompt"

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

Faults (``faults=`` or ``inject_fault``; the kinds in ``selfcal.hw.emulator.faults``): ``timeout``,
``garble``, ``drop``, ``impact``, ``disconnect``, ``home_failure``.

The arm itself is an ``EmulatorBackend``: the emulator tells it where the arm came to rest and asks
it for the stereo pair seen there. After every rest (and at start) the pair is written as
``<frames_dir>/%06d_left.png`` / ``%06d_right.png`` -- *before* ``PRINT MFLAG`` reports 0 -- which
``selfcal.hw.cameras`` reads through ``cv2.VideoCapture`` (``cv2.CAP_IMAGES``, ``"latest"`` mode).

The parts: ``selfcal.hw.emulator.backends`` (the arm), ``selfcal.hw.emulator.motion`` (its motion in encoder
counts), ``selfcal.hw.emulator.controller`` (the controller's state and dialogue), ``selfcal.hw.emulator.faults``,
``selfcal.hw.emulator.transport`` (the pty and TCP terminals); ``AclEmulator`` serves the controller on its
terminals and writes the frames.
"""

from __future__ import annotations

import json
import re
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from selfcal.errors import InputError, InternalError
from selfcal.hw.emulator.backends import EmulatorBackend
from selfcal.hw.emulator.controller import AclController
from selfcal.hw.emulator.transport import PtyPort, TcpPort, Terminal
from selfcal.io.atomic import write_image_atomic
from selfcal.robot.interface import StereoPair

__all__ = ["AclEmulator"]

_FRAME_FILE = re.compile(r"\d{6}_(left|right)\.png")


class AclEmulator(AclController):
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
            else ``EncoderTable.for_robot`` of its ``robot``).
        control_on: initial CON state.
        xon_in_replies: sprinkle XON (0x11) bytes into replies, as Controller-A may.
        pty_link: a path made a symbolic link to the pty (replaced on every start, removed on
            stop and on a disconnect), so a config can name a port that survives restarts.

    ``pty``, ``tcp_port``, ``frames_dir``, ``write_frames`` and ``pty_link`` are the emulator's;
    the other arguments go to the controller (``selfcal.hw.emulator.controller.AclController``).

    Frames left in ``frames_dir`` by an earlier run (``NNNNNN_left.png`` / ``_right.png``) are
    deleted at start: the cameras read the newest index, which would otherwise be a stale one.
    """

    def __init__(
        self,
        backend: EmulatorBackend | None = None,
        *,
        pty: bool = True,
        tcp_port: int | None = 0,
        frames_dir: str | Path | None = None,
        write_frames: bool = True,
        pty_link: str | Path | None = None,
        **controller: Any,
    ):
        super().__init__(backend, **controller)
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
        self._frame_index = 0

        self.pty_path: str | None = None
        self.tcp_address: tuple[str, int] | None = None
        self._pty: PtyPort | None = None
        self._tcp: TcpPort | None = None
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
            self._pty = PtyPort(self.pty_link)
            self.pty_path = self._pty.open()
            sess = Terminal(self, "pty", self._pty.write, self._pty.close)
            self.attach(sess)
            self._spawn(self._pty.serve, sess, self._stop)
        if self._want_tcp_port is not None:
            self._tcp = TcpPort(self, self._spawn, self._stop)
            self.tcp_address = self._tcp.open(int(self._want_tcp_port))
            self._spawn(self._tcp.accept_loop)
        self._spawn(self._tick_loop)
        return self

    def _remove_link(self) -> None:
        if self._pty is not None:
            self._pty.remove_link()

    def stop(self) -> None:
        """Stop serving and close everything (idempotent)."""
        self._stop.set()
        self._remove_link()
        for s in list(self.terminals):
            s.close()
        if self._tcp is not None:
            self._tcp.close()
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

    def _tick_loop(self) -> None:
        while not self._stop.wait(0.003):
            with self._lock:
                self._advance(time.monotonic())

    @property
    def url(self) -> str | None:
        """``socket://127.0.0.1:<port>`` of the TCP terminal, if served."""
        if self.tcp_address is None:
            return None
        return f"socket://{self.tcp_address[0]}:{self.tcp_address[1]}"

    @property
    def camera_sources(self) -> tuple[str, str]:
        """Image-sequence patterns (left, right) for ``selfcal.hw.cameras`` / ``[robot.hardware] cameras``."""
        if self.frames_dir is None:
            raise InternalError("the emulator writes no frames (write_frames=False, no frames_dir)")
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
            raise InternalError("the emulator is not started (no port yet)")
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

    # -- the controller's hooks ----------------------------------------------------------------

    def _disconnect_all(self) -> None:
        self._remove_link()  # the port a config names disappears with the pty
        super()._disconnect_all()  # the pty (master and slave) is closed: its path disappears

    # -- frames --------------------------------------------------------------------------------

    @property
    def frames_written(self) -> int:
        return self._frame_index

    def _rested(self) -> None:
        if self.write_frames and self.frames_dir is not None:
            pair = self.backend.capture()
            self._write_pair(self.frames_dir, pair)

    def _write_pair(self, frames_dir: Path, pair: StereoPair) -> None:
        i = self._frame_index
        for side, img in (("right", pair.right), ("left", pair.left)):  # right first: see cameras
            write_image_atomic(frames_dir / f"{i:06d}_{side}.png", img)
        self._frame_index = i + 1

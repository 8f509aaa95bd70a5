"""The ACL controller the emulator plays: its state (positions, control, faults) and its dialogue
(echo, prompt, questions, the commands; ``selfcal.hw.emulator.server`` lists what it answers), on the arm's
motion of ``selfcal.hw.emulator.motion``.

Each line a terminal (``selfcal.hw.emulator.transport``) delivers first brings the controller up to
``now`` (finished motions, scheduled events), then runs as one command under the lock; a fault
(``selfcal.hw.emulator.faults``) that fires on it may swallow, garble or cut the reply, or schedule an
impact, a disconnect or a home failure. ``selfcal.hw.emulator.server.AclEmulator`` serves the terminals and
writes the camera frames.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from selfcal.errors import InputError, UsageTypeError
from selfcal.hw.emulator.backends import EmulatorBackend, KinematicBackend
from selfcal.hw.emulator.faults import Fault, drop, garble, take_fault
from selfcal.hw.emulator.motion import ArmMotion, Segment
from selfcal.hw.emulator.transport import Terminal
from selfcal.hw.encoders import EncoderTable
from selfcal.kinematics.forward import fk_nominal
from selfcal.robot.definition import RobotDef, load_robot

__all__ = ["AclController"]


class AclController(ArmMotion):
    """An emulated SCORBOT controller (Controller-A style ACL, DIRECT mode), before any terminal
    is served.

    Args: see ``selfcal.hw.emulator.server.AclEmulator`` (``backend``, ``echo``, ``line_end``,
    ``move_speed_deg_s``, ``faults``, ``prompt_same_line``, ``home_duration_s``, ``encoders``,
    ``control_on``, ``xon_in_replies``).
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
        home_duration_s: float | None = None,
        encoders: EncoderTable | None = None,
        control_on: bool = True,
        xon_in_replies: bool = False,
    ):
        if line_end not in ("\r\n", "\r", "\n"):
            raise InputError(f"line_end must be '\\r\\n', '\\r' or '\\n', got {line_end!r}")
        if move_speed_deg_s <= 0:
            raise InputError(f"move_speed_deg_s must be positive, got {move_speed_deg_s}")
        backend = backend if backend is not None else KinematicBackend()
        encoders = encoders or getattr(backend, "encoders", None)
        if encoders is None:
            robot = getattr(backend, "robot", None)
            if robot is None:
                raise InputError(
                    "the emulator needs an encoder table: the backend has neither an `encoders` "
                    "table nor a `robot` model to build one from"
                )
            encoders = EncoderTable.for_robot(robot)
        if not isinstance(encoders, EncoderTable):
            raise UsageTypeError(f"encoders must be an EncoderTable, got {type(encoders).__name__}")
        super().__init__(backend, encoders, move_speed_deg_s)
        self.limits_deg = np.asarray(self.backend.limits_deg, dtype=float)
        if self.limits_deg.shape != (self.encoders.n, 2):
            raise InputError(
                f"backend limits_deg has shape {self.limits_deg.shape}, the encoder table has "
                f"{self.encoders.n} axes"
            )
        robot = getattr(self.backend, "robot", None)
        if not isinstance(robot, RobotDef):
            try:
                robot = load_robot(self.backend.model_name)
            except Exception:  # noqa: BLE001 - Cartesian line is optional
                robot = None
        self.robot = robot if robot is not None and robot.n == self.n else None
        self.echo_default = bool(echo)
        self.line_end = line_end
        self.prompt_same_line = bool(prompt_same_line)
        self.home_duration_s = home_duration_s
        self.xon_in_replies = bool(xon_in_replies)

        self._positions: dict[str, list[int | None]] = {}
        self._control = bool(control_on)
        self._faults: list[Fault] = [f if isinstance(f, Fault) else Fault(**f) for f in faults]
        self.terminals: list[Terminal] = []
        self.commands: list[str] = []
        self.received = bytearray()
        self.disconnected = False

    # -- terminals -----------------------------------------------------------------------------

    def attach(self, sess: Terminal) -> None:
        """Add a terminal (it receives broadcasts, e.g. an impact)."""
        with self._lock:
            self.terminals.append(sess)

    def detach(self, sess: Terminal) -> None:
        """Remove a closed terminal."""
        with self._lock:
            if sess in self.terminals:
                self.terminals.remove(sess)

    def ctrl_a(self) -> None:
        with self._lock:
            self.commands.append("^A")
            self._advance(time.monotonic())
            self._stop_motion()

    def _broadcast(self, text: str) -> None:
        for s in list(self.terminals):
            s.send(text)

    def _disconnect_all(self) -> None:
        self.disconnected = True
        for s in list(self.terminals):
            s.close()

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

    @property
    def control_on(self) -> bool:
        return self._control

    # -- the motion's hooks --------------------------------------------------------------------

    def _homing_complete(self, seg: Segment) -> None:
        if seg.session is not None:
            seg.session.send(self._format(["HOMING COMPLETE (ROBOT)"]))

    def _impacted(self, axis: int) -> None:
        self._control = False
        self._broadcast(f"{self.line_end}*** IMPACT PROTECTION axis {axis}{self.line_end}")

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

    def handle_line(self, sess: Terminal, line: str) -> None:
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
            fault = take_fault(self._faults, cmd) if cmd else None
            if fault is not None and fault.kind == "timeout" and not fault.execute:
                return
            out_lines, tail = self._execute(sess, cmd, fault, now)
            body = "".join(x + self.line_end for x in out_lines)
            if fault is not None and fault.kind == "garble":
                body = garble(body)
            elif fault is not None and fault.kind == "drop":
                body = drop(body)
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

    def _answer(self, sess: Terminal, cmd: str) -> str:
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
            p = fk_nominal(self.robot, np.radians(q))[0, -1, :3, 3] * 1e4  # tenths of a mm
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
        self, sess: Terminal, cmd: str, fault: Fault | None, now: float
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

"""``AclRobot``: a real SCORBOT (Controller-A/B, or an ACL bridge/emulator) as a ``selfcal.robot.interface.Robot``.

Motion: joint targets (deg) are checked against the model's ranges *before any byte is sent*,
converted to encoder counts (``selfcal.hw.encoders``), written into one reserved position with ``DEFP`` /
``SETPV pos axis value``, and run with ``MOVE pos`` (sent once, never retried). ``MOVE`` returns at
once; completion is polled with ``PRINT MFLAG`` until 0 (or ``LISTPV POSITION`` until still) within a
timeout, then the read-back is checked against the target.

Safety (the base class ``selfcal.hw.acl.guard.AclGuard``):
- a controller error that stops motion (any ``***`` line, ``AXIS DISABLED``) latches: motion is
  refused with ``AclLatchedError`` naming the axis and the controller's text until
  ``reset_errors()`` (which sends ``CON``);
- on any exception or KeyboardInterrupt while the arm may be moving, the first bytes sent are
  Ctrl-A (0x01) then ``CLRBUF``; ``close()`` sends them too;
- queries (``LISTPV``, ``PRINT MFLAG``, ...) are retried a bounded number of times, motion commands
  never.

Configuration: ``AclRobot.from_settings(settings)`` with typed ``selfcal.hw.settings.AclSettings``, or
``AclRobot.from_config(table)`` with a flat table of their keys (``docs/hardware.md``). Reading
them from a scenario is ``selfcal.acquisition.hardware``'s job.
"""

from __future__ import annotations

import re
import time
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np

from selfcal.errors import InputError, SelfCalWarning
from selfcal.hw.acl.errors import AclConnectionError, AclControllerError, AclProtocolError
from selfcal.hw.acl.guard import AclGuard
from selfcal.hw.acl.link import AclLink, port_hint
from selfcal.hw.acl.parsers import (
    AclVersion,
    parse_listpv,
    parse_mflag,
    parse_show_speed,
    parse_version,
)
from selfcal.hw.cameras import StereoCamera
from selfcal.hw.encoders import EncoderTable
from selfcal.hw.settings import DEFAULT_MODEL, AclSettings
from selfcal.robot.definition import RobotDef, load_robot, robot_files
from selfcal.robot.interface import RobotError, StereoPair

__all__ = ["AclRobot", "default_encoders"]

_HOME_DONE = re.compile(r"HOMING\s+COMPLETE", re.I)


def default_encoders(robot: RobotDef | str) -> EncoderTable:
    """The encoder table used when the config gives none: ``EncoderTable.for_robot(robot)``, from
    the model's ``[encoder]`` (encoder zero at its ``zero_deg``, else at its home posture)."""
    return EncoderTable.for_robot(robot)


class AclRobot(AclGuard):
    """A SCORBOT driven through ACL; implements ``selfcal.robot.interface.Robot``.

    Args:
        link: an open ``AclLink``.
        robot: the nominal model (name or ``RobotDef``): joint ranges and ``model_name``.
        encoders: counts <-> degrees (default: ``default_encoders(robot)``).
        cameras: a ``StereoCamera`` (or anything with ``capture() -> StereoPair`` and
            ``close()``), or ``None`` (``capture()`` then raises).
        Remaining arguments: see ``selfcal.hw.settings.AclSettings``.

    Not thread-safe: one caller at a time.
    """

    def __init__(
        self,
        link: AclLink,
        *,
        robot: RobotDef | str = DEFAULT_MODEL,
        encoders: EncoderTable | None = None,
        cameras: Any | None = None,
        position_name: str = "SCP",
        speed: int | None = None,
        home_timeout_s: float = 600.0,
        move_timeout_s: float = 120.0,
        poll_interval_s: float = 0.05,
        query_retries: int = 2,
        completion: str = "mflag",
        tolerance_counts: int = 10,
        coff_on_close: bool = False,
        start_grace_s: float = 0.5,
    ):
        super().__init__(
            link, load_robot(robot) if isinstance(robot, str) else robot, query_retries
        )
        self.model_name = self.robot.name
        self.encoders = encoders or default_encoders(self.robot)
        if self.encoders.n != self.robot.n:
            raise InputError(
                f"the encoder table has {self.encoders.n} axes but {self.robot.name} has "
                f"{self.robot.n} joints"
            )
        if any(t != "revolute" for t in self.robot.joint_types):
            raise InputError(f"{self.robot.name}: AclRobot supports revolute joints only")
        self.cameras = cameras
        self.position_name = position_name.upper()
        self.speed = speed
        self.home_timeout_s = float(home_timeout_s)
        self.move_timeout_s = float(move_timeout_s)
        self.poll_interval_s = float(poll_interval_s)
        if completion not in ("mflag", "listpv"):
            raise InputError(f"completion must be 'mflag' or 'listpv', got {completion!r}")
        self.completion = completion
        self.tolerance_counts = int(tolerance_counts)
        self.coff_on_close = bool(coff_on_close)
        self.start_grace_s = float(start_grace_s)
        self._position_defined = False
        self._speed_set = False

    # -- construction ----------------------------------------------------------------------------

    @classmethod
    def from_settings(
        cls,
        settings: AclSettings,
        *,
        link: AclLink | None = None,
        cameras: Any | None = None,
        open_cameras: bool = True,
    ) -> AclRobot:
        """Open the port and cameras that ``settings`` name.

        ``link``/``cameras`` replace what the settings would open; ``open_cameras=False`` skips
        them (e.g. for ``hw joints``).

        Raises:
            InputError: a bad encoder table. AclConnectionError: the port cannot be opened or
            nothing answers on it. CameraError: a camera cannot be opened.
        """
        s = settings
        robot = load_robot(s.model)
        encoders = default_encoders(robot)
        if s.encoders:
            encoders = EncoderTable.from_config(s.encoders, base=encoders)
        elif robot.encoder is not None and not robot.encoder.zero_stated:
            warnings.warn(
                f"[robot.hardware] has no encoders table: assuming the encoders read zero at "
                f"{robot.name}'s home posture {np.round(encoders.home_deg, 3).tolist()} deg (its "
                "TOML home_deg). On a real arm they read zero where HOME leaves it: give "
                "[robot.hardware.options.encoders] home_deg in this model's convention (or "
                f"[encoder] zero_deg in {robot_files().get(robot.name, 'its robot file')})",
                SelfCalWarning,
                stacklevel=3,
            )
        opened = link is None
        if link is None:
            link = AclLink.open(
                str(s.port),
                baudrate=int(s.baudrate),
                bytesize=int(s.bytesize),
                parity=str(s.parity),
                stopbits=s.stopbits,
                xonxoff=bool(s.xonxoff),
                echo=None if s.echo == "auto" else bool(s.echo),
                query_timeout_s=float(s.query_timeout_s),
                retries=int(s.query_retries),
            )
        try:
            if opened and s.connect_check and not link.resync(timeout_s=float(s.query_timeout_s)):
                raise AclConnectionError(
                    f"ACL port {s.port!r} opened but no prompt came back for a bare CR within "
                    f"{float(s.query_timeout_s):g} s: {port_hint(str(s.port))}"
                )
            if cameras is None and open_cameras and s.cameras:
                cameras = StereoCamera.from_sources(
                    list(s.cameras),
                    expected_size=s.camera_size,
                    sequence_mode=str(s.camera_sequence_mode),
                )
            return cls(
                link,
                robot=robot,
                encoders=encoders,
                cameras=cameras,
                position_name=str(s.position_name),
                speed=None if s.speed is None else int(s.speed),
                home_timeout_s=float(s.home_timeout_s),
                move_timeout_s=float(s.move_timeout_s),
                poll_interval_s=float(s.poll_interval_s),
                query_retries=int(s.query_retries),
                completion=str(s.completion),
                tolerance_counts=int(s.tolerance_counts),
                coff_on_close=bool(s.coff_on_close),
            )
        except BaseException:
            link.close()
            raise

    @classmethod
    def from_config(
        cls,
        table: Mapping[str, Any] | None,
        *,
        link: AclLink | None = None,
        cameras: Any | None = None,
        open_cameras: bool = True,
        **overrides: Any,
    ) -> AclRobot:
        """:meth:`from_settings` of a flat table of ``AclSettings`` keys (``overrides`` replace
        keys), e.g. ``{"port": "socket://127.0.0.1:5000", "cameras": []}``.

        Raises:
            InputError: unknown keys or bad values; and what :meth:`from_settings` raises.
        """
        settings = AclSettings.from_mapping({**(table or {}), **overrides})
        return cls.from_settings(settings, link=link, cameras=cameras, open_cameras=open_cameras)

    @classmethod
    def open(cls, port: str, **kwargs: Any) -> AclRobot:
        """``from_config({"port": port, **kwargs})`` without cameras unless ``cameras`` is given."""
        kwargs.setdefault("cameras", None)
        cams = kwargs.pop("cameras")
        return cls.from_config({"port": port, "cameras": cams or [], **kwargs})

    def __enter__(self) -> AclRobot:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- helpers ---------------------------------------------------------------------------------

    def _prepare_motion(self) -> None:
        """CON once, SPEED once, DEFP once; refuses on a latched error (before any byte)."""
        self._check_latch()
        self.link.drain()
        self._check_events("the check before motion")
        if not self._control_checked:
            reply = self._command("CON")
            if reply.lines and not any("ENABLED" in x.upper() for x in reply.lines):
                raise AclProtocolError(f"unexpected reply to CON: {reply.lines}", reply.raw)
            self._control_checked = True
        if self.speed is not None and not self._speed_set:
            self._command(f"SPEED {int(self.speed)}")
            self._speed_set = True
        if not self._position_defined:
            self._command(f"DEFP {self.position_name}")
            self._position_defined = True

    # -- the Robot protocol ------------------------------------------------------------------------

    def home(self) -> None:
        """``HOME`` with the long timeout; returns after ``HOMING COMPLETE``.

        Raises:
            AclLatchedError: an earlier error is latched (nothing is sent).
            AclControllerError: ``*** HOME FAILURE AXIS n`` or another controller error (latched).
            AclTimeoutError / AclConnectionError: no completion in time / link lost (abort sent).
        """
        self._check_open()
        self._check_latch()
        try:
            self._prepare_motion()
            self._may_move = True
            t0 = time.monotonic()
            reply = self.link.command("HOME", timeout_s=self.home_timeout_s)
            self._check_events("HOME")
            if not any(_HOME_DONE.search(x) for x in reply.lines):
                left = max(self.home_timeout_s - (time.monotonic() - t0), 0.1)
                _, m = self.link.read_lines_until(_HOME_DONE, left)
                self._check_events("HOME")
                if m is None:
                    raise AclProtocolError("HOME ended without HOMING COMPLETE")
            self._may_move = False
        except BaseException as exc:
            self._fail(exc, "HOME")
            raise

    def move_to(self, joints_deg: np.ndarray) -> None:
        """Move to joint angles (deg) and wait until the arm is still at them.

        Raises:
            ValueError: wrong length, non-finite or out-of-range joint (names the joint); nothing
                is sent.
            AclLatchedError: an earlier controller error is latched; nothing is sent.
            AclControllerError: the controller reported an error (latched if it stops motion).
            AclTimeoutError / AclProtocolError / AclConnectionError: no reply, garbled replies,
                link lost; the abort sequence is sent first.
            RobotError: the motion ended away from the target or took too long.
        """
        q = np.asarray(joints_deg, dtype=float)
        if q.shape != (self.n,):
            raise InputError(f"joints_deg must have {self.n} values, got shape {q.shape}")
        self.robot.check_joints(np.radians(q))  # ValueError naming the joint, before any byte
        target = self.encoders.to_counts(q)
        self._check_open()
        self._check_latch()
        try:
            self._prepare_motion()
            pos = self.position_name
            for axis in range(1, self.n + 1):
                self._command(f"SETPV {pos} {axis} {int(target[axis - 1])}")
            self._may_move = True
            self._command(f"MOVE {pos}")
            self._wait_still(target)
            self._may_move = False
        except BaseException as exc:
            self._fail(exc, f"MOVE to {np.round(q, 3).tolist()} deg")
            raise

    def _wait_still(self, target: np.ndarray) -> None:
        t0 = time.monotonic()
        deadline = t0 + self.move_timeout_s
        prev: np.ndarray | None = None
        while True:
            if self.completion == "mflag":
                still = self._query("PRINT MFLAG", parse_mflag) == 0
                counts = self._read_counts() if still else None
            else:
                counts = self._read_counts()
                still = prev is not None and np.array_equal(counts, prev)
                prev = counts
            if still and counts is not None:
                err = np.abs(counts - target)
                if np.all(err <= self.tolerance_counts):
                    return
                if time.monotonic() - t0 > self.start_grace_s:
                    worst = int(np.argmax(err))
                    raise RobotError(
                        f"the arm stopped {int(err[worst])} counts from the target on "
                        f"{self._axis_name(worst + 1)} (read {counts.tolist()}, target "
                        f"{target.tolist()}, tolerance {self.tolerance_counts})"
                    )
            if time.monotonic() > deadline:
                raise RobotError(
                    f"the move did not finish within {self.move_timeout_s:g} s "
                    "(move_timeout_s); the MOVE was not resent"
                )
            time.sleep(self.poll_interval_s)

    def _read_counts(self, raise_errors: bool = True) -> np.ndarray:
        lp = self._query("LISTPV POSITION", parse_listpv, raise_errors=raise_errors)
        return lp.axis_counts(self.n)

    def joints_counts(self) -> np.ndarray:
        """Current encoder counts of axes 1..n (``LISTPV POSITION``)."""
        self._check_open()
        return self._read_counts(raise_errors=False)

    def joints(self) -> np.ndarray:
        """Joint angles (deg) from ``LISTPV POSITION``; errors seen meanwhile are latched, not raised."""
        return self.encoders.to_degrees(self.joints_counts())

    def capture(self) -> StereoPair:
        """A stereo pair from the configured cameras (``RobotError`` if there are none)."""
        self._check_open()
        if self.cameras is None:
            raise RobotError(
                "no cameras configured for this robot: set [robot.hardware] cameras = [left, right]"
            )
        pair = self.cameras.capture()
        return StereoPair(pair.left, pair.right, {**pair.meta, "robot": "acl"})

    def close(self) -> None:
        """Abort any motion (Ctrl-A, CLRBUF), optionally COFF, close port and cameras. Idempotent."""
        if self._closed:
            return
        self._closed = True
        try:
            if self.link.is_open:
                self._abort()
                if self.coff_on_close:
                    try:
                        self.link.command("COFF", timeout_s=1.0)
                    except (AclProtocolError, AclControllerError):
                        pass
        except Exception:  # noqa: BLE001 - closing must not raise over a dead link
            pass
        finally:
            self.link.close()
            if self.cameras is not None:
                self.cameras.close()

    # -- extras ------------------------------------------------------------------------------------

    def version(self) -> AclVersion:
        """The controller's ``VER`` banner."""
        self._check_open()
        return self._query("VER", parse_version)

    def show_speed(self) -> dict[str, int]:
        """``SHOW SPEED`` as ``{"A": 50, ...}``."""
        self._check_open()
        return self._query("SHOW SPEED", parse_show_speed)

    def connection_ok(self) -> bool:
        """Whether a fresh prompt comes back for a bare CR."""
        self._check_open()
        try:
            return self.link.resync()
        except AclConnectionError:
            return False

"""The adapter's guarded ACL dialogue: ``AclGuard``, the base of ``selfcal.hw.acl.robot.AclRobot``.

- every controller error the link reports is raised (or, for read-only queries, warned about)
  with the axis and the controller's text named; an error that stops motion (any ``***`` line,
  ``AXIS DISABLED``) latches: motion is refused with ``AclLatchedError`` until ``reset_errors()``
  (which sends ``CON``);
- on any exception or KeyboardInterrupt while the arm may be moving, the first bytes sent are
  Ctrl-A (0x01) then ``CLRBUF`` (``_fail``); ``abort()`` sends them at once;
- queries are retried a bounded number of times (``query_retries``), commands never.
"""

from __future__ import annotations

import warnings
from typing import Any

from selfcal.hw.acl.errors import (
    AclControllerError,
    AclErrorEvent,
    AclLatchedError,
    AclProtocolError,
)
from selfcal.hw.acl.link import AclLink
from selfcal.hw.acl.reply import AclReply
from selfcal.robot.definition import RobotDef
from selfcal.robot.interface import RobotError

__all__ = ["AclGuard"]


class AclGuard:
    """Commands and queries over ``link`` with controller errors latched and raised, and the abort
    sequence on failure.

    Args:
        link: an open ``AclLink``.
        robot: the nominal model (axis names in messages).
        query_retries: extra attempts for a query.
    """

    def __init__(self, link: AclLink, robot: RobotDef, query_retries: int = 2):
        self.link = link
        self.robot = robot
        self.query_retries = int(query_retries)
        self.latched_error: AclErrorEvent | None = None
        self.abort_count = 0
        self._may_move = False
        self._control_checked = False
        self._closed = False

    @property
    def n(self) -> int:
        return self.robot.n

    def _axis_name(self, axis: int | None) -> str:
        if axis is None:
            return "no axis named"
        if 1 <= axis <= self.n:
            return f"axis {axis} ({self.robot.joint_names[axis - 1]})"
        return f"axis {axis}"

    def _check_open(self) -> None:
        if self._closed:
            raise RobotError("the robot connection is closed")

    def _check_latch(self) -> None:
        ev = self.latched_error
        if ev is not None:
            raise AclLatchedError(
                f"motion refused: the controller reported '{ev.message}' ({self._axis_name(ev.axis)}); "
                "check the arm, then call reset_errors() (sends CON)",
                ev,
            )

    def _latch(self, ev: AclErrorEvent) -> None:
        if self.latched_error is None:
            self.latched_error = ev
        self._control_checked = False

    def _check_events(self, during: str, raise_errors: bool = True) -> None:
        """Consume the link's error events: latch the latching ones, raise for any."""
        events = self.link.pop_events()
        first: AclErrorEvent | None = None
        for ev in events:
            if ev.latching:
                self._latch(ev)
            first = first or ev
        if first is not None:
            if raise_errors:
                latched = (
                    " (latched: motion refused until reset_errors())" if first.latching else ""
                )
                raise AclControllerError(
                    f"controller reported '{first.message}' ({self._axis_name(first.axis)}) "
                    f"during {during}{latched}",
                    first,
                )
            warnings.warn(
                f"controller reported '{first.message}' during {during}",
                RuntimeWarning,
                stacklevel=3,
            )

    def _command(self, cmd: str, timeout_s: float | None = None) -> AclReply:
        reply = self.link.command(cmd, timeout_s=timeout_s)
        self._check_events(cmd)
        if reply.question is not None:
            raise AclProtocolError(
                f"the controller asks {reply.question!r} after {cmd!r}; the adapter does not answer "
                "questions",
                reply.raw,
            )
        return reply

    def _query(self, cmd: str, parse: Any, raise_errors: bool = True) -> Any:
        """A query with bounded retries; controller errors seen meanwhile are latched and (with
        ``raise_errors``) raised, else warned about."""
        try:
            value = self.link.query(cmd, parse, retries=self.query_retries)
        except AclControllerError:
            self._check_events(cmd, raise_errors=True)  # raises the annotated error if any
            raise
        self._check_events(cmd, raise_errors=raise_errors)
        return value

    def _abort(self) -> list[str]:
        """Ctrl-A then CLRBUF (first bytes sent); latches any error that shows up."""
        self.abort_count += 1
        problems = self.link.abort()
        for ev in self.link.pop_events():
            if ev.latching:
                self._latch(ev)
        return problems

    def _fail(self, exc: BaseException, during: str) -> None:
        """On failure while the arm may move: abort first, then annotate ``exc``."""
        if not self._may_move:
            return
        self._may_move = False
        problems = self._abort()
        if problems:
            note = (
                f"abort sequence (Ctrl-A, CLRBUF) after the failure in {during} could not be "
                f"delivered: {'; '.join(problems)} -- the arm may still be moving: use the "
                "emergency stop"
            )
        else:
            note = f"abort sequence (Ctrl-A, CLRBUF) sent after the failure in {during}"
        if hasattr(exc, "add_note"):
            exc.add_note(note)
        if isinstance(exc, RobotError) and exc.args and isinstance(exc.args[0], str):
            # in the message too: callers that wrap the error (the acquisition loop, the CLI)
            # print str(exc), and whether the arm was stopped must reach the person at the robot
            exc.args = (f"{exc.args[0]} [{note}]", *exc.args[1:])

    def reset_errors(self) -> None:
        """Clear the latched error after checking the arm: ``CLRBUF``, ``CON``, unlatch.

        Raises:
            AclControllerError: the controller still reports an error.
        """
        self._check_open()
        self.link.pop_events()
        self._command("CLRBUF")
        reply = self._command("CON")
        if reply.lines and not any("ENABLED" in x.upper() for x in reply.lines):
            raise AclProtocolError(f"unexpected reply to CON: {reply.lines}", reply.raw)
        self.latched_error = None
        self._control_checked = True

    def abort(self) -> None:
        """Send the abort sequence now (Ctrl-A, CLRBUF)."""
        self._check_open()
        self._may_move = False
        self._abort()

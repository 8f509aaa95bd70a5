"""The ACL adapter's error types, and the recognition of the controller's error lines.

``parse_error_line`` recognises one line (``*** ...`` or a known plain message such as ``NO
POSITION ASSIGNED TO POINT pos``) as an ``AclErrorEvent``; ``split_error`` finds one that starts
mid-line, ``extract_error_events`` all of them in a block of text.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from selfcal.hw.acl.text import LINE_SPLIT, MAX_INT_DIGITS
from selfcal.robot.interface import RobotError

__all__ = [
    "AclProtocolError",
    "AclTimeoutError",
    "AclConnectionError",
    "AclControllerError",
    "AclLatchedError",
    "AclErrorEvent",
    "parse_error_line",
    "split_error",
    "extract_error_events",
]


class AclProtocolError(RobotError):
    """The controller's reply was garbled, incomplete or unexpected; ``raw`` holds the bytes."""

    def __init__(self, message: str, raw: bytes = b"", events: tuple = ()):
        super().__init__(message)
        self.raw = bytes(raw)
        self.events = tuple(events)


class AclTimeoutError(AclProtocolError):
    """No complete reply (no prompt) within the timeout; ``raw`` holds what did arrive."""


class AclConnectionError(AclProtocolError):
    """The serial link itself failed (port closed, device unplugged, socket disconnected)."""


@dataclass(frozen=True)
class AclErrorEvent:
    """One error reported by the controller.

    Attributes:
        kind: ``impact_protection``, ``out_of_range``, ``thermic_overload``, ``trajectory_error``,
            ``upper_limit``, ``lower_limit``, ``home_failure``, ``no_position``,
            ``bad_point_coordinate``, ``bad_cartesian_point``, ``axis_disabled`` or
            ``controller_error`` (any other ``***`` line).
        message: the controller's text, stripped.
        axis: the axis number the message names (1-based), if any.
        position: the position name (``NO POSITION ASSIGNED TO POINT pos``), if any.
    """

    kind: str
    message: str
    axis: int | None = None
    position: str | None = None

    @property
    def asynchronous(self) -> bool:
        """``***`` errors are printed asynchronously (e.g. during a motion)."""
        return self.message.startswith("***")

    @property
    def latching(self) -> bool:
        """Errors after which the adapter refuses motion until control is re-enabled."""
        return self.asynchronous or self.kind == "axis_disabled"

    def __str__(self) -> str:
        return self.message


class AclControllerError(RobotError):
    """The controller reported an error (``event``); the message names axis and controller text."""

    def __init__(self, message: str, event: AclErrorEvent | None = None):
        super().__init__(message)
        self.event = event

    @property
    def axis(self) -> int | None:
        return self.event.axis if self.event else None


class AclLatchedError(AclControllerError):
    """Motion refused: an earlier controller error is latched until ``reset_errors()``."""


_AXIS_ERRORS = {
    "IMPACT PROTECTION": "impact_protection",
    "OUT OF RANGE": "out_of_range",
    "THERMIC OVERLOAD": "thermic_overload",
    "UPPER LIMIT": "upper_limit",
    "LOWER LIMIT": "lower_limit",
    "HOME FAILURE": "home_failure",
}
_STAR_RE = re.compile(r"\*\*\*\s*(?P<msg>.*)$")
_AXIS_ERR_RE = re.compile(
    r"^(?P<what>" + "|".join(_AXIS_ERRORS) + r")\s*(?:ON\s+)?AXIS\s*(?P<axis>\d+)", re.IGNORECASE
)
_PLAIN_ERRORS = (
    (re.compile(r"^NO\s+POSITION\s+ASSIGNED\s+TO\s+POINT\s*(?P<pos>\S*)", re.I), "no_position"),
    (re.compile(r"^BAD\s+POINT\s+COORDINATE", re.I), "bad_point_coordinate"),
    (re.compile(r"^BAD\s+CARTESIAN\s+POINT", re.I), "bad_cartesian_point"),
    (re.compile(r"^AXIS\s+DISABLED(?:\s+(?P<axis>\d+))?", re.I), "axis_disabled"),
)


def _axis_number(digits: str | None) -> int | None:
    """The axis an error line names; ``None`` if it names none or a number no axis can have."""
    if not digits or len(digits.lstrip("0")) > MAX_INT_DIGITS:
        return None
    return int(digits)


def parse_error_line(line: str) -> AclErrorEvent | None:
    """Recognise one controller error line (``*** ...`` or a known plain message), else ``None``."""
    text = line.strip().lstrip(">").strip()
    m = _STAR_RE.match(text)
    if m:
        msg = m.group("msg").strip()
        message = f"*** {msg}"
        am = _AXIS_ERR_RE.match(msg)
        if am:
            kind = _AXIS_ERRORS[re.sub(r"\s+", " ", am.group("what").upper())]
            return AclErrorEvent(kind, message, axis=_axis_number(am.group("axis")))
        if re.match(r"^TRAJECTORY\s+ERROR", msg, re.I):
            return AclErrorEvent("trajectory_error", message)
        for rx, kind in _PLAIN_ERRORS:
            pm = rx.match(msg)
            if pm:
                gd = pm.groupdict()
                axis = _axis_number(gd.get("axis"))
                return AclErrorEvent(kind, message, axis=axis, position=gd.get("pos") or None)
        return AclErrorEvent("controller_error", message)
    for rx, kind in _PLAIN_ERRORS:
        pm = rx.match(text)
        if pm:
            gd = pm.groupdict()
            axis = _axis_number(gd.get("axis"))
            return AclErrorEvent(kind, text, axis=axis, position=gd.get("pos") or None)
    return None


def split_error(line: str) -> tuple[str, AclErrorEvent | None]:
    """Split a line into (text before an error, error event). ``***`` may start mid-line."""
    idx = line.find("***")
    if idx >= 0:
        return line[:idx], parse_error_line(line[idx:])
    ev = parse_error_line(line)
    if ev is not None:
        return "", ev
    return line, None


def extract_error_events(text: str) -> list[AclErrorEvent]:
    """All error events in a block of text (any line ends)."""
    out = []
    for line in LINE_SPLIT.split(text):
        _, ev = split_error(line)
        if ev is not None:
            out.append(ev)
    return out

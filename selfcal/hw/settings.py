"""``AclSettings``: what the ACL adapter needs to open a robot, typed, with defaults and checks.

The fields are the keys of a scenario's ``[robot.hardware]`` table (``docs/hardware.md``), but
``hw`` takes only these plain settings: reading them out of a scenario or a TOML file is
``selfcal.acquisition.hardware``'s job. ``AclSettings.from_mapping`` builds them from a flat table of those
keys and refuses unknown ones with the list of known ones.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from selfcal.errors import InputError

__all__ = ["AclSettings", "DEFAULT_HARDWARE", "DEFAULT_MODEL"]

DEFAULT_MODEL = "er4u-vendor"
"""The model (``models/<folder>/<name>.toml``) of an ACL controller's arm when none is named."""

_POSITION_NAME = re.compile(r"[A-Za-z][A-Za-z0-9]{0,4}")


@dataclass(frozen=True)
class AclSettings:
    """The ACL adapter's settings (units in the names). Raises :class:`InputError` on bad values."""

    model: str = DEFAULT_MODEL
    """Nominal model (``models/<folder>/<name>.toml``): joint ranges and ``model_name``."""
    port: str = "/dev/ttyUSB0"
    """Any pyserial URL: device, ``socket://host:port``, ``loop://``, pty path."""
    baudrate: int = 9600
    bytesize: int = 8
    parity: str = "N"
    stopbits: float = 1
    xonxoff: bool = True
    echo: str | bool = "auto"
    """``"auto"`` | True | False: what the controller does (not changed)."""
    cameras: tuple[str, ...] = ("0", "1")
    """Left, right: device index, URL or image-sequence pattern; empty for no cameras."""
    camera_size: tuple[int, int] | None = None
    """(width, height) to enforce, or None."""
    camera_sequence_mode: str = "latest"
    """Image sequences: ``"latest"`` (live/emulator) | ``"next"``."""
    query_timeout_s: float = 2.0
    home_timeout_s: float = 600.0
    move_timeout_s: float = 120.0
    poll_interval_s: float = 0.05
    query_retries: int = 2
    position_name: str = "SCP"
    """The one ACL position the adapter reserves (``DEFP``)."""
    speed: int | None = None
    """``SPEED 1..100`` sent before the first motion, or None (leave as is)."""
    completion: str = "mflag"
    """``"mflag"`` (``PRINT MFLAG`` until 0) | ``"listpv"`` (``LISTPV`` until still)."""
    tolerance_counts: int = 10
    """Read-back vs target after a move, per axis (motor counts)."""
    coff_on_close: bool = False
    connect_check: bool = True
    """On opening, a bare CR must bring a prompt (else a clear error)."""
    encoders: Mapping[str, Any] | None = None
    """Encoder table (``counts_per_deg``, ``home_deg``, ``home_counts``, ``differential``; see
    ``selfcal.hw.encoders.EncoderTable.from_config``), or None for the model's default."""

    def __post_init__(self) -> None:
        def fix(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        fix("cameras", tuple(str(c) for c in self.cameras))
        if self.camera_size is not None:
            fix("camera_size", tuple(int(v) for v in self.camera_size))
        if self.completion not in ("mflag", "listpv"):
            raise InputError(f"completion must be 'mflag' or 'listpv', got {self.completion!r}")
        if self.echo not in ("auto", True, False):
            raise InputError(f"echo must be 'auto', true or false, got {self.echo!r}")
        if self.speed is not None and not 1 <= int(self.speed) <= 100:
            raise InputError(f"speed must be 1..100, got {self.speed}")
        if not _POSITION_NAME.fullmatch(str(self.position_name)):
            raise InputError(
                f"position_name must be 1-5 letters/digits starting with a letter, got "
                f"{self.position_name!r}"
            )

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any] | None) -> AclSettings:
        """Settings from a flat table of the keys above (missing keys take their defaults).

        Raises:
            InputError: unknown keys (the message lists the known ones) or bad values.
        """
        table = dict(table or {})
        known = [f.name for f in dataclasses.fields(cls)]
        unknown = set(table) - set(known)
        if unknown:
            raise InputError(
                f"unknown [robot.hardware] key(s) {sorted(unknown)}; known: {sorted(known)}"
            )
        return cls(**table)

    def as_dict(self) -> dict[str, Any]:
        """The settings as a ``[robot.hardware]`` table (lists, not tuples)."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["cameras"] = list(self.cameras)
        if self.camera_size is not None:
            out["camera_size"] = list(self.camera_size)
        return out


DEFAULT_HARDWARE: dict[str, Any] = AclSettings().as_dict()
"""Every ``[robot.hardware]`` key with its default (read-only by convention)."""

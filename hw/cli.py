"""Command-line subcommands for the hardware adapter, registered into the ``selfcal`` CLI.

``register(subparsers)`` adds:

- ``hw joints``  -> prints ``{"joints_deg": [...]}``
- ``hw home``    -> HOME, then prints ``{"homed": true, "joints_deg": [...]}``
- ``hw move --joints a,b,c,d,e`` -> moves, then prints ``{"joints_deg": [...]}`` (read back)
- ``emulate [CONFIG]`` -> runs the ACL emulator (kinematic backend) until Ctrl-C

``hw`` commands take ``--port URL`` (any pyserial URL) or ``--config FILE`` (TOML with a
``[robot.hardware]`` table), optionally ``--model NAME``. Each parser sets ``func`` (called as
``func(args) -> int`` exit code).
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np

from scenarios.robot import RobotError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["register", "load_toml", "EMULATOR_DEFAULTS"]

EMULATOR_DEFAULTS: dict[str, Any] = {
    "model": "er4u-vendor",
    "pty": True,
    "tcp_port": 0,
    "echo": True,
    "line_end": "\r\n",
    "prompt_same_line": False,
    "move_speed_deg_s": 60.0,
    "home_duration_s": 1.0,
    "frames_dir": None,
    "image_size": [640, 480],
}


def load_toml(path: str | Path) -> dict[str, Any]:
    """Read a TOML file; ``ValueError`` names the file on a missing file or a syntax error."""
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"config file not found: {p}")
    try:
        return tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{p}: not valid TOML: {exc}") from exc


def _add_conn_args(p: argparse.ArgumentParser) -> None:
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--port", help="pyserial URL: /dev/ttyUSB0, socket://host:port, a pty path")
    g.add_argument("--config", help="TOML file with a [robot.hardware] table")
    p.add_argument("--model", help="robot model name (default: from the config or er4u-vendor)")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``hw {joints,home,move}`` and ``emulate`` to an argparse subparsers object."""
    hw = subparsers.add_parser("hw", help="the real robot over ACL (serial)")
    hw_sub = hw.add_subparsers(dest="hw_command", required=True)

    p = hw_sub.add_parser("joints", help='print {"joints_deg": [...]} read from the encoders')
    _add_conn_args(p)
    p.set_defaults(func=_cmd_joints)

    p = hw_sub.add_parser("home", help="run HOME (takes minutes on a real arm)")
    _add_conn_args(p)
    p.set_defaults(func=_cmd_home)

    p = hw_sub.add_parser("move", help="move to joint angles (deg)")
    _add_conn_args(p)
    p.add_argument("--joints", required=True, help="comma-separated joint angles in deg: a,b,c,d,e")
    p.set_defaults(func=_cmd_move)

    p = subparsers.add_parser("emulate", help="run the ACL controller emulator until Ctrl-C")
    p.add_argument("config", nargs="?", help="optional TOML file with an [emulator] table")
    p.set_defaults(func=_cmd_emulate)


def _open_robot(args: argparse.Namespace):
    from hw.acl_robot import AclRobot

    if args.config:
        config = load_toml(args.config)
    else:
        config = {"robot": {"hardware": {"port": args.port}}}
    overrides = {"model": args.model} if args.model else {}
    return AclRobot.from_config(config, open_cameras=False, **overrides)


def _print(obj: dict[str, Any]) -> None:
    print(json.dumps(obj), flush=True)


def _run(args: argparse.Namespace, body) -> int:
    try:
        robot = _open_robot(args)
    except (ValueError, RobotError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    try:
        with robot:
            body(robot)
        return 0
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except RobotError as exc:
        notes = "".join(f"\n  {n}" for n in getattr(exc, "__notes__", []))
        print(f"error: {exc}{notes}", file=sys.stderr)
        return 1


def _joints_list(robot) -> list[float]:
    return [round(float(x), 4) for x in robot.joints()]


def _cmd_joints(args: argparse.Namespace) -> int:
    return _run(args, lambda r: _print({"joints_deg": _joints_list(r)}))


def _cmd_home(args: argparse.Namespace) -> int:
    def body(r) -> None:
        r.home()
        _print({"homed": True, "joints_deg": _joints_list(r)})

    return _run(args, body)


def _parse_joints(text: str) -> np.ndarray:
    try:
        return np.array([float(x) for x in text.split(",") if x.strip()], dtype=float)
    except ValueError as exc:
        raise ValueError(f"--joints must be comma-separated numbers (deg), got {text!r}") from exc


def _cmd_move(args: argparse.Namespace) -> int:
    try:
        q = _parse_joints(args.joints)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2

    def body(r) -> None:
        r.move_to(q)
        _print({"joints_deg": _joints_list(r)})

    return _run(args, body)


def emulator_from_config(config: dict[str, Any] | None):
    """An (unstarted) ``AclEmulator`` with the kinematic backend from an ``[emulator]`` table."""
    from hw.emulator import AclEmulator, KinematicBackend

    config = dict(config or {})
    table = dict(config.get("emulator", {}))
    model = table.pop("model", None) or config.get("robot", {}).get("model") or "er4u-vendor"
    unknown = set(table) - set(EMULATOR_DEFAULTS)
    if unknown:
        raise ValueError(
            f"unknown [emulator] key(s) {sorted(unknown)}; known: {sorted(EMULATOR_DEFAULTS)}"
        )
    cfg = {**EMULATOR_DEFAULTS, **table}
    backend = KinematicBackend(model, image_size=tuple(cfg["image_size"]))
    return AclEmulator(
        backend,
        echo=bool(cfg["echo"]),
        line_end=str(cfg["line_end"]),
        move_speed_deg_s=float(cfg["move_speed_deg_s"]),
        prompt_same_line=bool(cfg["prompt_same_line"]),
        pty=bool(cfg["pty"]),
        tcp_port=None if cfg["tcp_port"] is None else int(cfg["tcp_port"]),
        frames_dir=cfg["frames_dir"],
        home_duration_s=cfg["home_duration_s"],
    )


def _cmd_emulate(args: argparse.Namespace, stop_event: threading.Event | None = None) -> int:
    try:
        emu = emulator_from_config(load_toml(args.config) if args.config else None)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    stop = stop_event or threading.Event()
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda *_: stop.set())
    with emu:
        left, right = emu.camera_sources if emu.frames_dir else (None, None)
        print(f"ACL emulator, kinematic backend ({emu.backend.model_name})")
        if emu.pty_path:
            print(f"pty: {emu.pty_path}")
        if emu.url:
            print(f"tcp: {emu.url}")
        if left:
            print(f"cameras: {left} {right}")
        print("config:")
        print("[robot.hardware]")
        print(f'port = "{emu.pty_path or emu.url}"')
        if left:
            print(f'cameras = ["{left}", "{right}"]')
        print("Ctrl-C to stop", flush=True)
        try:
            while not stop.wait(0.2):
                pass
        except KeyboardInterrupt:
            pass
    print("emulator stopped", flush=True)
    return 0

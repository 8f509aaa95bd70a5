"""``selfcal hw ...`` and ``selfcal emulate``: the hardware adapter and the controller emulator on
the command line (registered into ``selfcal.cli.main``).

``register(subparsers)`` adds:

- ``hw joints``  -> prints ``{"joints_deg": [...]}``
- ``hw home``    -> HOME, then prints ``{"homed": true, "joints_deg": [...]}``
- ``hw move --joints a,b,c,d,e`` -> moves, then prints ``{"joints_deg": [...]}`` (read back)
- ``emulate [CONFIG]`` -> runs the ACL emulator until Ctrl-C: with a scenario TOML the arm is that
  scenario's simulated robot (``selfcal.acquisition.emulator_backend``), else a kinematic arm

``hw`` commands take ``--port URL`` (any pyserial URL) or ``--config FILE`` (TOML with a
``[robot.hardware]`` table), optionally ``--model NAME``. Each parser sets ``func`` (called as
``func(args) -> int``); errors propagate to ``selfcal.console.common.run_command``, which prints
them and picks the exit code.
"""

from __future__ import annotations

import argparse
import json
import signal
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

from selfcal.config.defaults import DEFAULT_ROBOT
from selfcal.console.common import add_deprecated, add_json, parse_floats
from selfcal.console.progress import Progress
from selfcal.errors import InputError

if TYPE_CHECKING:
    from selfcal.hw.acl.robot import AclRobot

# Heavy modules (scipy, OpenCV, MuJoCo, the pipeline) are imported by the functions that use
# them, so that `selfcal --help` builds every command's parser without loading them.
__all__ = ["register", "load_toml", "EMULATOR_DEFAULTS", "emulator_from_config"]

EMULATOR_DEFAULTS: dict[str, Any] = {
    "model": DEFAULT_ROBOT,
    "pty": True,
    "tcp_port": 0,
    "echo": True,
    "line_end": "\r\n",
    "prompt_same_line": False,
    "move_speed_deg_s": 60.0,
    "home_duration_s": 1.0,
    "frames_dir": None,
    "image_size": [640, 480],
    "pty_link": None,
    "scenario": None,
}


def load_toml(path: str | Path) -> dict[str, Any]:
    """Read a TOML file; ``InputError`` names the file on a missing or unreadable file or a
    syntax error (:func:`selfcal.tomlfile.read_toml`, the reader of every TOML input)."""
    from selfcal.tomlfile import read_toml

    return read_toml(path, InputError, what="config file")


def _add_conn_args(p: argparse.ArgumentParser) -> None:
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--port", help="pyserial URL: /dev/ttyUSB0, socket://host:port, a pty path")
    g.add_argument("--config", help="TOML file with a [robot.hardware] table")
    p.add_argument(
        "--robot",
        default=None,
        help="robot model name: its [encoder] table turns the controller's counts into joint "
        f"angles (default: the config's [robot] model, else {DEFAULT_ROBOT}; a real ER-4u: "
        "er4u-vendor)",
    )
    add_deprecated(p, "--model", "--robot", dest="robot")
    add_json(p, always=True)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``hw {joints,home,move}`` and ``emulate`` to an argparse subparsers object."""
    from selfcal.acquisition.emulate_faults import CLI_FAULTS

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

    p = subparsers.add_parser(
        "emulate",
        help="run the ACL controller emulator until Ctrl-C",
        description="Run the ACL controller emulator until Ctrl-C. With a scenario TOML the arm is "
        "that scenario's simulated robot (its injected errors, the flange cameras' rendered "
        "frames; an eye-to-hand scenario is refused); with an "
        "[emulator] TOML or nothing, a kinematic arm. Prints the pty path, the TCP address and "
        "the [robot.hardware] table to paste into a scenario.",
    )
    p.add_argument(
        "config",
        nargs="?",
        help="a scenario TOML (simulated robot) or a TOML with an [emulator] table",
    )
    p.add_argument("--tcp-port", type=int, default=None, help="TCP port on 127.0.0.1 (0: any)")
    p.add_argument("--frames-dir", default=None, help="where the stereo frames are written")
    p.add_argument(
        "--pty-link",
        default=None,
        help="a symbolic link to the pty: a port name that survives restarts",
    )
    p.add_argument("--move-speed", type=float, default=None, help="joint speed, deg/s at SPEED 50")
    p.add_argument(
        "--fault",
        choices=[*CLI_FAULTS, "random"],
        default=None,
        help="inject one fault into the acquisition (docs/hardware.md, 'Rehearsing faults')",
    )
    p.add_argument(
        "--fault-at",
        type=int,
        default=None,
        metavar="N",
        help="the acquisition frame (0-based) the fault hits (default: drawn from --seed)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of a random fault kind or frame")
    p.set_defaults(func=_cmd_emulate)


def _open_robot(args: argparse.Namespace) -> AclRobot:
    from selfcal.acquisition.hardware import hardware_settings
    from selfcal.hw.acl.robot import AclRobot

    config = load_toml(args.config) if args.config else {"port": args.port}
    section = config.get("robot")
    robot = section if isinstance(section, dict) else {}
    hardware = robot.get("hardware")
    named = robot.get("model") or (hardware.get("model") if isinstance(hardware, dict) else None)
    # the one default (selfcal.config.scenario.DEFAULT_ROBOT) unless the command line or config names one
    overrides = {"model": args.robot or (None if named else DEFAULT_ROBOT)}
    overrides = {k: v for k, v in overrides.items() if v}
    return AclRobot.from_settings(hardware_settings(config, **overrides), open_cameras=False)


def _print(obj: dict[str, Any]) -> None:
    print(json.dumps(obj), flush=True)


def _run(args: argparse.Namespace, body) -> int:
    """Open the robot, run ``body(robot)``, close it. Errors propagate to the ``selfcal`` entry
    point, which prints them and exits with their code (bad input 2, hardware fault 4)."""
    with _open_robot(args) as robot:
        body(robot)
    return 0


def _state(robot) -> dict[str, Any]:
    """The robot's model (whose encoder table converted the counts) and its joints (deg)."""
    return {"robot": robot.model_name, "joints_deg": _joints_list(robot)}


def _joints_list(robot) -> list[float]:
    return [round(float(x), 4) for x in robot.joints()]


def _cmd_joints(args: argparse.Namespace) -> int:
    return _run(args, lambda r: _print(_state(r)))


def _cmd_home(args: argparse.Namespace) -> int:
    def body(r) -> None:
        with Progress("hw", enabled=not args.quiet).step("homing (minutes on a real arm)"):
            r.home()
        _print({"homed": True, **_state(r)})

    return _run(args, body)


def _cmd_move(args: argparse.Namespace) -> int:
    q = parse_floats(args.joints, None, "--joints (deg)")

    def body(r) -> None:
        with Progress("hw", enabled=not args.quiet).step(f"moving to {args.joints} deg"):
            r.move_to(q)
        _print(_state(r))

    return _run(args, body)


def _emulator_kwargs(cfg: dict[str, Any]) -> dict[str, Any]:
    return dict(
        echo=bool(cfg["echo"]),
        line_end=str(cfg["line_end"]),
        move_speed_deg_s=float(cfg["move_speed_deg_s"]),
        prompt_same_line=bool(cfg["prompt_same_line"]),
        pty=bool(cfg["pty"]),
        tcp_port=None if cfg["tcp_port"] is None else int(cfg["tcp_port"]),
        frames_dir=cfg["frames_dir"],
        home_duration_s=cfg["home_duration_s"],
        pty_link=cfg["pty_link"],
    )


def emulator_from_config(
    config: dict[str, Any] | None,
    *,
    scenario: Any = None,
    overrides: dict[str, Any] | None = None,
):
    """An (unstarted) ``AclEmulator`` from an ``[emulator]`` table.

    The arm is the simulated robot of a scenario (``selfcal.acquisition.emulator_backend.SimEmulatorBackend``)
    when ``scenario`` (a ``Scenario``) is given or the table names one (``scenario = "path"``,
    relative to the working directory), else the kinematic backend of ``model``. ``overrides``
    replace table keys (from the command line).

    Raises:
        InputError: unknown keys; ``ConfigError`` (an ``InputError``) for a bad scenario.
    """
    from selfcal.acquisition.emulator_backend import SimEmulatorBackend
    from selfcal.config.scenario import load_scenario
    from selfcal.hw.emulator.backends import EmulatorBackend, KinematicBackend
    from selfcal.hw.emulator.server import AclEmulator

    config = dict(config or {})
    table = dict(config.get("emulator", {}))
    table.update({k: v for k, v in (overrides or {}).items() if v is not None})
    model = table.pop("model", None) or config.get("robot", {}).get("model")
    unknown = set(table) - set(EMULATOR_DEFAULTS)
    if unknown:
        raise InputError(
            f"unknown [emulator] key(s) {sorted(unknown)}; known: {sorted(EMULATOR_DEFAULTS)}"
        )
    cfg = {**EMULATOR_DEFAULTS, **table}
    if scenario is None and cfg["scenario"]:
        scenario = load_scenario(cfg["scenario"])
    if scenario is not None:
        if model is not None and model != scenario.robot.model:
            raise InputError(
                f"[emulator] model {model!r} contradicts the scenario's [robot] model "
                f"{scenario.robot.model!r}: the simulated robot is the scenario's"
            )
        backend: EmulatorBackend = SimEmulatorBackend.from_scenario(
            scenario, seed=scenario.noise.seed
        )
    else:
        backend = KinematicBackend(model or DEFAULT_ROBOT, image_size=tuple(cfg["image_size"]))
    try:
        return AclEmulator(backend, **_emulator_kwargs(cfg))
    except BaseException:
        if hasattr(backend, "close"):
            backend.close()
        raise


def _is_scenario_file(config: dict[str, Any]) -> bool:
    """A TOML without an ``[emulator]`` table and with any other key is a scenario."""
    return "emulator" not in config and bool(config)


def _cmd_emulate(args: argparse.Namespace, stop_event: threading.Event | None = None) -> int:
    from selfcal.acquisition.emulate_faults import acquisition_fault, choose_fault
    from selfcal.config.scenario import load_scenario

    overrides = {
        "tcp_port": getattr(args, "tcp_port", None),
        "frames_dir": getattr(args, "frames_dir", None),
        "pty_link": getattr(args, "pty_link", None),
        "move_speed_deg_s": getattr(args, "move_speed", None),
    }
    fault, fault_text = None, None
    if getattr(args, "fault", None):
        kind, at = choose_fault(args.fault, args.fault_at, args.seed)
        fault = acquisition_fault(kind, at)
        fault_text = f"fault: {kind} at acquisition frame {at} (seed {args.seed})"
    elif getattr(args, "fault_at", None) is not None:
        raise InputError("--fault-at needs --fault", fix="add --fault timeout|garble|impact|...")
    config = load_toml(args.config) if args.config else None
    scenario = None
    if config is not None and _is_scenario_file(config):
        scenario = load_scenario(args.config)
    emu = emulator_from_config(
        None if scenario is not None else config, scenario=scenario, overrides=overrides
    )
    if fault is not None:
        emu.inject_fault(fault)
    stop = stop_event or threading.Event()
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        with emu:
            kind = (
                "simulated robot of the scenario"
                if type(emu.backend).__name__ == "SimEmulatorBackend"
                else "kinematic backend"
            )
            print(f"ACL emulator, {kind} ({emu.backend.model_name})")
            if emu.pty_path:
                print(f"pty: {emu.pty_path}")
            if emu.pty_link is not None:
                print(f"pty link: {emu.pty_link}")
            if emu.url:
                print(f"tcp: {emu.url}")
            if emu.frames_dir is not None:
                left, right = emu.camera_sources
                print(f"cameras: {left} {right}")
            if fault_text:
                print(fault_text)
            print("config:")
            print(emu.hardware_snippet(), end="")
            print("Ctrl-C to stop", flush=True)
            try:
                while not stop.wait(0.2):
                    pass
            except KeyboardInterrupt:
                pass
    finally:
        if hasattr(emu.backend, "close"):
            emu.backend.close()
    print("emulator stopped", flush=True)
    return 0

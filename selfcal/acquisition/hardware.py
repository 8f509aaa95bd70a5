"""A scenario's hardware backend: its ``[robot.hardware]`` table -> ``selfcal.hw.settings.AclSettings``
-> ``selfcal.hw.acl.robot.AclRobot``.

``hw`` takes plain typed settings; this module knows where they stand in a scenario: ``port``,
``baudrate``, ``xonxoff``, ``cameras`` in ``[robot.hardware]`` itself, every further adapter key in
``[robot.hardware.options]``, the model in ``[robot] model`` and the frame size in ``[camera]
resolution`` (``docs/hardware.md``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from selfcal.config.scenario import ConfigError, Scenario
from selfcal.errors import InputError
from selfcal.hw.acl.errors import AclConnectionError
from selfcal.hw.acl.robot import AclRobot, default_encoders
from selfcal.hw.encoders import EncoderTable
from selfcal.hw.settings import AclSettings

__all__ = ["hardware_settings", "scenario_settings", "open_hardware_robot"]

_SCENARIO_HW_KEYS = ("model", "port", "baudrate", "xonxoff", "cameras")


def hardware_settings(config: Mapping[str, Any] | None, **overrides: Any) -> AclSettings:
    """The adapter settings of a config dict: a whole TOML document with ``[robot.hardware]``
    (``[robot] model`` is the model unless the table names one) or that table itself; an
    ``options`` table is merged in. ``overrides`` replace keys (from the command line).

    Raises:
        InputError: unknown keys (the message lists the known ones), a key given both directly
            and in ``options``, or bad values.
    """
    config = dict(config or {})
    model = None
    if isinstance(config.get("robot"), Mapping):
        robot = config["robot"]
        model = robot.get("model")
        table = dict(robot.get("hardware") or {})
    else:
        table = config
    options = table.pop("options", None)
    if options is not None:
        if not isinstance(options, Mapping):
            raise InputError(f"[robot.hardware] options must be a table, got {options!r}")
        clash = set(options) & set(table)
        if clash:
            raise InputError(
                f"[robot.hardware] key(s) {sorted(clash)} are given both directly and in options; "
                "give each once"
            )
        table.update(options)
    if model is not None and "model" not in table:
        table["model"] = model
    table.update(overrides)
    return AclSettings.from_mapping(table)


def scenario_settings(scenario: Scenario) -> AclSettings:
    """The adapter settings of a hardware scenario, checked as :func:`open_hardware_robot` opens
    them (without opening anything).

    Raises:
        ConfigError: an option that is unknown, belongs elsewhere, or contradicts the scenario
            (the message names the scenario file and the key).
    """
    hw = scenario.robot.hardware
    where = f"{scenario.source}: [robot.hardware] options"
    opts = dict(hw.options)
    misplaced = sorted(set(opts) & set(_SCENARIO_HW_KEYS))
    if misplaced:
        raise ConfigError(
            f"{where}: {misplaced} do not belong in options: give model in [robot] and "
            "port, baudrate, xonxoff, cameras directly in [robot.hardware]"
        )
    size = [int(v) for v in scenario.camera.resolution]
    if opts.get("camera_size") is not None and [int(v) for v in opts["camera_size"]] != size:
        raise ConfigError(
            f"{where}: camera_size {list(opts['camera_size'])} contradicts [camera] resolution "
            f"{size}; drop camera_size (the resolution is enforced) or fix the resolution"
        )
    table = {
        **opts,
        "model": scenario.robot.model,
        "port": hw.port,
        "baudrate": hw.baudrate,
        "xonxoff": hw.xonxoff,
        "cameras": [str(c) for c in hw.cameras],
        "camera_size": size,
    }
    try:
        settings = AclSettings.from_mapping(table)
        if settings.encoders:
            EncoderTable.from_config(settings.encoders, base=default_encoders(settings.model))
    except ValueError as exc:  # InputError, or a value of the wrong type
        raise ConfigError(f"{where}: {exc}") from None
    return settings


def open_hardware_robot(scenario: Scenario) -> AclRobot:
    """The scenario's robot on the hardware path: an ``AclRobot`` with its ``StereoCamera``.

    From the scenario: ``robot.model`` (nominal model: joint ranges, ``model_name``),
    ``robot.hardware.port`` / ``baudrate`` / ``xonxoff`` / ``cameras``, ``robot.hardware.options``
    (any further ``AclSettings`` key, e.g. ``query_timeout_s``, ``speed``, ``encoders``) and
    ``camera.resolution`` (frames of another size are refused). Without ``options.encoders`` the
    table is ``default_encoders(model)``. On opening, the controller must answer a bare CR with a
    prompt (``connect_check``).

    Raises:
        ConfigError: an option that is unknown, belongs elsewhere, or contradicts the scenario
            (the message names the scenario file and the key).
        AclConnectionError: the port cannot be opened or nothing answers on it (the message
            names the URL and what to check).
        CameraError: a camera source cannot be opened or gives no frame.
    """
    settings = scenario_settings(scenario)
    try:
        return AclRobot.from_settings(settings)
    except AclConnectionError as exc:
        raise AclConnectionError(
            f"{scenario.source}: [robot.hardware] port: {exc}", exc.raw, exc.events
        ) from exc

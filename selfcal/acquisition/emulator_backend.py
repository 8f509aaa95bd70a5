"""The simulated robot behind the ACL controller emulator: ``selfcal.hw.emulator.backends.EmulatorBackend``
over ``selfcal.sim.sim_robot.SimRobot``.

With it the hardware path (``[robot] backend = "hardware"``: ``selfcal.hw.acl.robot.AclRobot`` over a
serial port, ``selfcal.hw.cameras`` reading image files) runs against the *simulated* actual robot of a
scenario, with its injected kinematic errors, and the test still holds the ground truth.

How a rest is simulated: the emulated controller moves its encoder counts to the commanded target
and reports the rest at ``encoders.to_degrees(counts)``. The real arm stops somewhere inside that
count cell, so the backend places the simulated arm at the motor counts plus a uniform offset of
up to ``rest_jitter_counts`` per motor (seeded), converts that through the same encoder table
(differential wrist included) and lets the encoders read the commanded counts. The joint
read-back therefore carries the encoder quantisation error exactly as on the real arm.

It needs both lower layers (``sim`` for the arm, ``hw`` for the encoder table and the emulator's
backend protocol), so it lives here, in the top layer, which may import both.

Threads: the emulator calls ``set_joints_deg`` and ``capture`` from its own threads; MuJoCo's
offscreen GL context belongs to the thread that created it, so every call on the ``SimRobot``
(moves, renders, truth) runs on one worker thread owned by this backend. Do not use the
``SimRobot`` directly while the backend serves it.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from selfcal.acquisition.backends import make_sim_robot
from selfcal.config.scenario import Scenario
from selfcal.errors import InputError, InternalError
from selfcal.hw.encoders import EncoderTable
from selfcal.io.truth import Truth
from selfcal.robot.definition import RobotDef
from selfcal.robot.interface import StereoPair
from selfcal.sim.sim_robot import SimRobot

__all__ = ["SimEmulatorBackend", "sim_robot_for_scenario"]


def sim_robot_for_scenario(scenario: Scenario) -> SimRobot:
    """The scenario's simulated actual robot, built as the ``sim`` backend builds it
    (``selfcal.acquisition.backends.make_sim_robot``)."""
    return make_sim_robot(scenario)


class SimEmulatorBackend:
    """A ``SimRobot`` as the arm of ``selfcal.hw.emulator.server.AclEmulator``.

    Args:
        sim_robot: the simulated robot (its ``actual`` chain carries the injected errors). The
            backend owns it from now on and closes it in ``close()``.
        encoders: the controller's encoder table (default ``EncoderTable.for_robot(robot)``:
            zero at the model's TOML home posture, resolution from its ``[encoder]``). The
            emulator uses this table unless given another one.
        rest_jitter_counts: the arm rests within +-this many counts of the commanded counts on
            every motor (uniform, seeded); 0 puts it exactly on the count.
        seed: seed of the rest jitter.

    Attributes:
        model_name, limits_deg, robot, encoders: the ``EmulatorBackend`` protocol.
        rests: one record per rest: ``counts`` (what the encoders read), ``commanded_deg`` and
            ``true_deg`` (where the simulated arm is).
    """

    def __init__(
        self,
        sim_robot: SimRobot,
        *,
        encoders: EncoderTable | None = None,
        rest_jitter_counts: float = 0.5,
        seed: int = 0,
    ) -> None:
        if not 0.0 <= rest_jitter_counts <= 0.5:
            raise InputError(
                f"rest_jitter_counts must be in [0, 0.5] (inside the count cell the encoders "
                f"read), got {rest_jitter_counts}"
            )
        self.sim = sim_robot
        self.robot: RobotDef = sim_robot.robot
        self.model_name = sim_robot.model_name
        if any(t != "revolute" for t in self.robot.joint_types):
            raise InputError(f"{self.model_name}: the ACL emulator drives revolute joints only")
        self.limits_deg = np.degrees(self.robot.limits)
        self.encoders = encoders if encoders is not None else EncoderTable.for_robot(self.robot)
        if self.encoders.n != self.robot.n:
            raise InputError(
                f"encoder table has {self.encoders.n} axes, {self.model_name} has {self.robot.n}"
            )
        self.rest_jitter_counts = float(rest_jitter_counts)
        self._rng = np.random.default_rng(seed)
        self._worker = ThreadPoolExecutor(1, thread_name_prefix="sim-emulator-backend")
        self._closed = False
        self.rests: list[dict[str, np.ndarray]] = []

    @classmethod
    def from_scenario(cls, scenario: Scenario, **kwargs: Any) -> SimEmulatorBackend:
        """Backend over ``sim_robot_for_scenario(scenario)``; ``kwargs`` go to the constructor."""
        return cls(sim_robot_for_scenario(scenario), **kwargs)

    def _call(self, fn: Any, *args: Any) -> Any:
        if self._closed:
            raise InternalError("SimEmulatorBackend is closed")
        return self._worker.submit(fn, *args).result()

    # -- EmulatorBackend ---------------------------------------------------------------------------

    def set_joints_deg(self, joints_deg: np.ndarray) -> np.ndarray | None:
        """The controller came to rest at ``joints_deg`` (deg, a count lattice point): put the
        simulated arm somewhere in that count cell; the encoders read the commanded counts."""
        q_cmd = np.asarray(joints_deg, dtype=float).reshape(self.robot.n)
        counts = self.encoders.to_counts(q_cmd)
        j = self.rest_jitter_counts
        motor = counts + (self._rng.uniform(-j, j, counts.shape) if j > 0 else 0.0)
        q_true = self.encoders.to_degrees(motor)
        # the arm cannot pass its end stops (the controller allows targets within a count of them)
        q_rad = np.clip(np.radians(q_true), self.robot.limits[:, 0], self.robot.limits[:, 1])
        self._call(self.sim.move_to, np.degrees(q_rad))
        self.rests.append({"counts": counts, "commanded_deg": q_cmd, "true_deg": np.degrees(q_rad)})
        return None

    def capture(self) -> StereoPair:
        """The rendered stereo pair at the current posture (with the scenario's image noise)."""
        return self._call(self.sim.capture)

    # -- ground truth (tests, never the calibration) ---------------------------------------------

    def truth(self, meta: dict | None = None) -> Truth:
        """The ground-truth header: nominal and true MCPC chains, rig, marker field, ``T_cam_tip``."""
        return self._call(self.sim.truth, meta)

    def truth_frame(self) -> dict:
        """``SimRobot.truth_frame()`` of the current posture (true joints, camera poses, tip)."""
        return self._call(self.sim.truth_frame)

    def true_joints_deg(self) -> np.ndarray:
        """Where the simulated arm is (deg), unquantised."""
        return np.degrees(self._call(self.sim.true_joints))

    def close(self) -> None:
        """Close the simulated robot (frees the renderer on its own thread); idempotent."""
        if self._closed:
            return
        try:
            self._call(self.sim.close)
        finally:
            self._closed = True
            self._worker.shutdown(wait=True)

    def __enter__(self) -> SimEmulatorBackend:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"SimEmulatorBackend({self.model_name!r}, rests={len(self.rests)})"

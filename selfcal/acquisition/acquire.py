"""The one acquisition loop: drive any ``Robot`` along planned postures into a dataset on disk.

The loop knows nothing of the backend: the simulator and the hardware adapter are both ``Robot``s.
Observers that only a simulator has (analytic corner projections, ground truth) are passed in as
optional callbacks by the caller. Images are encoded and written by one worker thread while the
robot moves to and captures the next posture (PNG encoding releases the GIL), a frame's images
side by side (the second on a helper thread: the encodings and the waits for the disk's fsync
overlap); at most one frame is in flight, and a frame is complete on disk before the next one
is handed over. With a :class:`selfcal.io.frame_cache.FrameCache` another helper thread keeps
each image meanwhile as the gray pixels the calibration would read back (``selfcal run``
calibrates from memory) and detects its markers there (:attr:`FrameCache.on_image`).
With :class:`selfcal.acquisition.held_frames.HeldFrames` (a simulated ``selfcal run``) the
frames' files are written by its own thread instead, into the calibration's time.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from selfcal.acquisition.held_frames import HeldFrames
from selfcal.acquisition.stopped import AcquisitionError, stopped
from selfcal.console.progress import Progress
from selfcal.io.dataset import DatasetWriter
from selfcal.io.frame_cache import FrameCache
from selfcal.robot.interface import Robot

__all__ = ["AcquisitionError", "AcquisitionHooks", "acquire"]


@dataclass
class AcquisitionHooks:
    """Optional simulator-side callbacks.

    ``detect``: returns ``{"left": {id: (4,2)}, "right": {...}}`` for the current posture (analytic
    path; without it the loop captures images). ``record_truth(index)``: store ground truth of the
    frame just taken (simulation only). ``finish()``: called once when the loop ends, also on
    an error (writes what the hooks kept, e.g. ``truth.json``).
    """

    detect: Callable[[], dict[str, dict[int, np.ndarray]]] | None = None
    record_truth: Callable[[int], None] | None = None
    finish: Callable[[], None] | None = None


def _shown(
    cameras: tuple[str, ...], left: np.ndarray, right: np.ndarray | None
) -> dict[str, np.ndarray]:
    """The images of a frame by camera name, of the dataset's ``cameras`` (a camera without an
    image, e.g. ``right`` of a one-camera robot, left out)."""
    images = {"left": left, "right": right}
    return {c: v for c, v in images.items() if c in cameras and v is not None}


def acquire(
    robot: Robot,
    writer: DatasetWriter,
    *,
    hooks: AcquisitionHooks | None = None,
    progress: Progress | None = None,
    keep: FrameCache | None = None,
    resume_command: str | None = None,
    held: HeldFrames | None = None,
) -> int:
    """Take every planned frame that the dataset does not hold yet; returns frames taken now.
    ``keep``: also keep the images taken in memory (:meth:`FrameCache.add`). ``resume_command``:
    the command that continues this acquisition, named when it stops (default ``selfcal acquire
    SCENARIO --out ROOT --resume``). ``held``: hand the captured frames to it instead of
    writing them (:class:`HeldFrames`: written on its own thread, while the loop
    and the caller go on; the caller's ``with held:`` waits for them); when the loop stops on an error, every frame
    taken before is written first.

    Raises:
        AcquisitionError: a robot or camera failure; every frame taken before it is kept on disk
            and ``selfcal acquire ... --resume`` continues from there.
        ValueError: a planned posture outside the joint ranges (raised by the robot before it moves).
    """
    hooks = hooks or AcquisitionHooks()
    plan = writer.info.planned_joints_deg
    done = set(writer.done)
    todo = [i for i in range(len(plan)) if i not in done]
    taken = 0
    if progress is not None:
        progress.start(len(plan), done=len(plan) - len(todo))
    pending: list[tuple[int, Future]] = []  # the frame the worker is writing
    cameras = writer.info.cameras
    resume_command = resume_command or f"selfcal acquire SCENARIO --out {writer.root} --resume"
    if held is not None:
        held.attach(writer, len(plan), resume_command)

    def store(i: int, q: np.ndarray, left: np.ndarray, right: np.ndarray | None) -> None:
        """Write frame ``i`` (the worker thread; the second image on ``helpers``) and keep its
        images meanwhile (on the other helper: the cache's gray images and detections)."""
        if held is not None:  # keep the images (here), the files later
            if keep is not None:
                keep.add(i, _shown(cameras, left, right))
            held.hold(i, q, left, right)
            return
        kept = None
        if keep is not None:
            kept = helpers.submit(keep.add, i, _shown(cameras, left, right))
        try:
            writer.add_frame(i, q, left=left, right=right, executor=helpers)
        finally:
            if kept is not None:
                kept.result()

    def stop(j: int, exc: BaseException) -> AcquisitionError:
        """The error that stops the acquisition at frame ``j``, the frames held written first."""
        if held is not None:
            held.drain()
        return stopped(j, len(plan), writer, exc, resume_command)

    def settle() -> None:
        """Wait for the frame in flight; its failure stops the acquisition at that frame."""
        while pending:
            j, fut = pending.pop()
            try:
                fut.result()
            except (Exception, KeyboardInterrupt) as exc:
                raise stop(j, exc) from exc

    with (
        ThreadPoolExecutor(max_workers=1, thread_name_prefix="frame-writer") as pool,
        ThreadPoolExecutor(max_workers=2, thread_name_prefix="frame-helper") as helpers,
    ):
        try:
            for i in todo:
                try:
                    robot.move_to(plan[i])
                    q = robot.joints()
                    if hooks.detect is not None:
                        writer.add_frame(i, q, detections=hooks.detect())
                    else:
                        pair = robot.capture()
                        settle()  # the previous frame is on disk (or held) before this one is handed over
                        fut = pool.submit(store, i, q, pair.left, pair.right)
                        pending.append((i, fut))
                    if hooks.record_truth is not None:
                        hooks.record_truth(i)
                except (ValueError, AcquisitionError):
                    raise
                except (Exception, KeyboardInterrupt) as exc:
                    settle()
                    raise stop(i, exc) from exc
                taken += 1
                if progress is not None:
                    progress.advance()
            settle()
        finally:
            for _, fut in pending:  # an error elsewhere: let the frame in flight land
                fut.exception()
            if hooks.finish is not None:
                hooks.finish()
    if progress is not None:
        progress.finish()
    return taken

"""Frames a simulated ``selfcal run`` has taken but not yet written: their PNGs are encoded and
written by a thread of their own, beside the acquisition and the calibration, which runs from
the images in memory.

The simulator keeps both cores busy while it acquires (rendering, the image noise, the marker
detection); the calibration after it runs on one. Encoding the PNGs (a fifth of the
acquisition's CPU) therefore costs wall time during the acquisition and little beside the
calibration. :class:`HeldFrames` takes each frame's images from the acquisition loop
(:func:`selfcal.acquisition.acquire.acquire`) and writes them on one thread of its own, at the
process's priority (the lowest was tried and dropped: any CPU-bound process beside it can
starve it until the loop waits on it, :data:`HOLD_BYTES`, and idle it has nothing to yield
to), from the loop's first frame, in order and by :meth:`selfcal.io.dataset.DatasetWriter.add_frame` (the same files, byte for byte; a frame counts as taken once its joints row follows its images, as
always); the loop waits when the frames not yet written exceed :data:`HOLD_BYTES`. It hands the
calibration the dataset as the writer will leave it (:meth:`HeldFrames.dataset`).

Nothing taken is lost on an error or Ctrl-C: leaving the ``with`` block writes every frame held
before the error goes on (:meth:`HeldFrames.drain`), and the interpreter's exit waits for the
writing thread as well. A frame that cannot be written stops the writing there, as in the
loop: the error names the frame, the frames kept and the command that continues. It stops the
acquisition too: the next frame handed over (:meth:`HeldFrames.hold`) raises it, so the loop
stops at the frame after that (the loop itself at the next one; before, the simulator rendered
every posture left and the error came only at the end). A process
killed outright (SIGKILL, or SIGTERM, which Python does not turn into an exception) loses the
frames still held, where the loop loses at most the frame in flight: the simulator renders them
again on ``selfcal run``'s resume.
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor
from types import TracebackType

import numpy as np

from selfcal.acquisition.stopped import AcquisitionError, stopped
from selfcal.errors import InternalError
from selfcal.io.dataset import Dataset, DatasetWriter, joints_row, read_text

__all__ = ["HOLD_BYTES", "HeldFrames"]

HOLD_BYTES = 256 * 2**20
"""Images not yet written before the acquisition waits for the writer (~145 stereo frames of
640 x 480 RGB)."""

_Frame = tuple[int, np.ndarray, np.ndarray, np.ndarray | None]


class HeldFrames:
    """The frames of one acquisition whose files are written after it (module docstring).

    Use it as a context manager around the acquisition and what runs from memory after it;
    :func:`selfcal.acquisition.acquire.acquire` ``held=`` attaches it to its writer."""

    def __init__(self, max_bytes: int = HOLD_BYTES) -> None:
        self.max_bytes = max_bytes
        self._writer: DatasetWriter | None = None
        self._n_planned = 0
        self._resume_command: str | None = None
        self._joints_csv = ""  # joints.csv as the writer will leave it
        self._pool: ThreadPoolExecutor | None = None
        # index, bytes and write of each frame not yet on disk (or whose write failed)
        self._writes: list[tuple[int, int, Future]] = []
        self._failed = False

    def attach(self, writer: DatasetWriter, n_planned: int, resume_command: str | None) -> None:
        """Write into ``writer``'s dataset (``n_planned`` frames planned; ``resume_command``
        continues it after a failed write, as :func:`selfcal.acquisition.stopped.stopped`)."""
        self._writer = writer
        self._n_planned = n_planned
        self._resume_command = resume_command
        self._joints_csv = read_text(writer.root / "joints.csv")
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="held-writer")

    @property
    def pending(self) -> int:
        """Frames held whose files are not yet known to be on disk."""
        return sum(not f.done() for _, _, f in self._writes)

    def hold(
        self, index: int, joints_deg: np.ndarray, left: np.ndarray, right: np.ndarray | None
    ) -> None:
        """Hand frame ``index`` (its joint read-back, deg, and images) to the writing thread;
        waits while the frames not yet written exceed ``max_bytes``.

        Raises:
            AcquisitionError: an earlier frame could not be written (:meth:`drain`'s error; the
                failed write stays held, so the acquisition's :meth:`drain` raises it again).
        """
        writer = self._require()
        assert self._pool is not None
        failure = self._failure()
        if failure is not None:  # stop the acquisition now, not after every posture left
            raise self._stopped(*failure) from failure[1]
        self._joints_csv += joints_row(index, joints_deg)
        frame = (index, np.asarray(joints_deg), left, right)
        nbytes = left.nbytes + (0 if right is None else right.nbytes)
        self._writes.append((index, nbytes, self._pool.submit(self._write, writer, frame)))
        # frames on disk are forgotten (a failed one is kept for drain): the list, and this scan,
        # stay as long as the frames not yet written, not the whole acquisition
        self._writes = [w for w in self._writes if not w[2].done() or w[2].exception() is not None]
        unwritten = [(n, f) for _, n, f in self._writes if not f.done()]
        while unwritten and sum(n for n, _ in unwritten) > self.max_bytes:
            unwritten.pop(0)[1].exception()  # the oldest written (or failed): drain reports it

    def dataset(self) -> Dataset:
        """The dataset as the writer will leave it, every frame held included (its
        ``joints.csv`` rows from memory; dataset.json from the folder)."""
        return Dataset.open(self._require().root, joints_csv=self._joints_csv)

    def drain(self) -> None:
        """Write every frame held and wait until they are on disk.

        Raises:
            AcquisitionError: a frame could not be written (the frames after it are not
                written either): the message names it, the frames kept and the command that
                continues.
        """
        for _, _, fut in self._writes:
            fut.exception()  # wait for it
        failure = self._failure()
        self._writes = []
        if failure is not None:
            raise self._stopped(*failure) from failure[1]

    def __enter__(self) -> HeldFrames:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        try:
            self.drain()
        finally:
            if self._pool is not None:
                self._pool.shutdown(wait=True)

    def _write(self, writer: DatasetWriter, frame: _Frame) -> None:
        """Frame ``frame`` into the dataset; none after a failed one (its error is raised)."""
        index, q, left, right = frame
        if self._failed:
            raise InternalError(f"frame {index} not written: an earlier frame failed")
        try:
            writer.add_frame(index, q, left=left, right=right)
        except BaseException:
            self._failed = True
            raise

    def _failure(self) -> tuple[int, BaseException] | None:
        """The first held frame whose write has failed, with its error (None: none has yet)."""
        for index, _, fut in self._writes:
            exc = fut.exception() if fut.done() else None
            if exc is not None:
                return index, exc
        return None

    def _stopped(self, index: int, exc: BaseException) -> AcquisitionError:
        """The error that stops the acquisition at the held frame ``index`` whose write failed
        with ``exc``."""
        return stopped(index, self._n_planned, self._require(), exc, self._resume_command)

    def _require(self) -> DatasetWriter:
        if self._writer is None:
            raise InternalError("HeldFrames.attach(writer, ...) first (acquire(held=...) does)")
        return self._writer

"""Why an acquisition stopped, what it kept and how to continue: the one error both the loop
(:func:`selfcal.acquisition.acquire.acquire`) and the frames written after it
(:class:`selfcal.acquisition.held_frames.HeldFrames`) raise."""

from __future__ import annotations

from selfcal.errors import HardwareError
from selfcal.io.dataset import DatasetWriter

__all__ = ["AcquisitionError", "stopped"]


class AcquisitionError(HardwareError):
    """Acquisition stopped; the message says how many frames are safe and how to resume."""


def stopped(
    i: int, n: int, writer: DatasetWriter, exc: BaseException, resume_command: str | None
) -> AcquisitionError:
    """The error that stops the acquisition at frame ``i`` of ``n``: why, what is kept and the
    command that continues (a Ctrl-C's ``KeyboardInterrupt`` has no text of its own)."""
    if isinstance(exc, KeyboardInterrupt):
        reason = "interrupted (Ctrl-C)"
    else:
        reason = str(exc) or type(exc).__name__
    command = resume_command or f"selfcal acquire SCENARIO --out {writer.root} --resume"
    return AcquisitionError(
        f"acquisition stopped at frame {i} of {n}: {reason}. "
        f"{writer.n_done} frames are kept in {writer.root}; continue with `{command}`"
    )

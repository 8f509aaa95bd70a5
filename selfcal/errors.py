"""The one exception root of scorbot-selfcal and its kinds.

Every error the project raises derives from :class:`SelfCalError` (tests/unit/test_raises.py
fails on a bare builtin ``raise``). Its message names the file, key, row or quantity at fault;
``fix`` (optional) says what the user can do about it. The command line catches the root, prints
``message`` and ``fix`` and exits with the kind's ``exit_code`` (README: "Exit codes"); a kind
whose code is :data:`EXIT_INTERNAL` (a bug: :class:`UsageError`, :class:`InternalError`) is
printed as an internal error. The kinds keep the builtin they used to be (``ValueError`` for bad
input or a bad argument, ``TypeError`` for an argument of the wrong type, ``RuntimeError`` for a
failure, ``OSError`` for a file that cannot be written) so ``except ValueError`` in callers still
works.
"""

from __future__ import annotations

__all__ = [
    "SelfCalError",
    "InputError",
    "EstimationError",
    "SolverError",
    "HardwareError",
    "OutputError",
    "UsageError",
    "UsageTypeError",
    "InternalError",
    "SelfCalWarning",
    "InitialCameraWarning",
    "EXIT_OK",
    "EXIT_INTERNAL",
    "EXIT_INTERRUPTED",
    "EXIT_BROKEN_PIPE",
]

EXIT_OK = 0
EXIT_INTERNAL = 1
"""An error the project did not raise on purpose: a bug (``SELFCAL_DEBUG=1`` shows the trace)."""
EXIT_INTERRUPTED = 130
EXIT_BROKEN_PIPE = 141
"""The reader of the output went away (``selfcal scenarios | head -1``): 128 + SIGPIPE, the status
a Unix tool ends with there; nothing is reported."""


class SelfCalError(Exception):
    """Root of every error raised on purpose. ``fix``: what the user can do, or None."""

    exit_code: int = EXIT_INTERNAL

    def __init__(self, message: str = "", *, fix: str | None = None) -> None:
        super().__init__(message)
        self.fix = fix

    @property
    def message(self) -> str:
        """The message alone, without the fix (to re-raise with more context, or to print)."""
        return super().__str__()

    def __str__(self) -> str:
        return f"{self.message} (fix: {self.fix})" if self.fix else self.message


class InputError(SelfCalError, ValueError):
    """Bad input: a scenario, dataset, robot file, calibration file or command-line argument."""

    exit_code = 2


class EstimationError(SelfCalError, RuntimeError):
    """The data cannot determine what was asked: too few views, degenerate geometry, no
    convergence, a result worse than the nominal model."""

    exit_code = 3


class SolverError(EstimationError):
    """The least-squares engine stopped on non-finite numbers or an unsolvable system; the
    message names the residual or parameter block."""


class HardwareError(SelfCalError, RuntimeError):
    """The robot, its controller, the serial link or a camera failed."""

    exit_code = 4


class OutputError(SelfCalError, OSError):
    """A file or device could not be written (an image format OpenCV cannot encode, a path that
    is taken, a closed pseudo-terminal): exit code 2, the message names it."""

    exit_code = 2


class UsageError(SelfCalError, ValueError):
    """The calling program broke a function's contract (an argument's shape, length or range,
    two arguments that disagree): a bug in the caller, so the command line reports it as an
    internal error (exit code 1). What a user wrote (a file, a key, a flag) is an
    :class:`InputError`."""


class UsageTypeError(UsageError, TypeError):
    """An argument of the wrong type (a :class:`UsageError` that is also a ``TypeError``)."""


class InternalError(SelfCalError, RuntimeError):
    """The project's own state or result is wrong (an object used after it was closed or before
    it was started, a check of its own result that fails): a bug, exit code 1."""


class SelfCalWarning(UserWarning):
    """Root of the project's warnings (something the user should know; never data)."""


class InitialCameraWarning(SelfCalWarning):
    """A given initial camera (a ROS CameraInfo's calibration) fitted the images worse than the
    calibration's own start, which is used instead (the board and the field calibration)."""

"""The pybotics side of the tracker benchmark, run in pybotics' own environment (it pins
numpy < 2, so :mod:`selfcal.benchmarks.tracker` starts it with ``uv run --no-project --with
pybotics --with 'numpy<2' python selfcal/benchmarks/tracker/pybotics_fit.py IN.npz OUT.npz``).

pybotics' documented calibration: a modified-DH chain (``alpha, a, theta, d`` per link, mm and
rad), an :class:`pybotics.optimization.OptimizationHandler` with masks, and
``scipy.optimize.least_squares`` on ``pybotics.optimization.optimize_accuracy`` (one residual per
measurement: the norm of the position error). Unknowns: the world frame (6), the tool position
(3) and the link parameters of links 2..n except ``theta_n, d_n`` (the tool absorbs them); link
1's parameters are redundant with the world frame. The start (world frame, tool point) is the
same closed-form placement the project's identification starts from, handed over in IN.npz.

IN.npz: ``mdh`` (n, 4) nominal, ``world0`` (4, 4) mm, ``tool0`` (3,) mm, ``q_train`` (N, n)
rad, ``xyz_train`` (N, 3) mm, ``q_test`` (M, n), ``repeats``. OUT.npz: ``pred_test`` (M, 3) mm,
``seconds`` (repeats,) wall, ``cpu_seconds`` (repeats,) of this process, ``nfev``,
``version``.
"""

from __future__ import annotations

import sys
import time


def main(argv: list[str]) -> int:
    """Fit and write OUT.npz (see the module docstring)."""
    from importlib.metadata import version

    import numpy as np
    import scipy.optimize
    from pybotics.optimization import (  # type: ignore[import-not-found]
        OptimizationHandler,
        optimize_accuracy,
    )
    from pybotics.robot import Robot  # type: ignore[import-not-found]

    with np.load(argv[0]) as npz:
        data = dict(npz)
    mdh = data["mdh"]
    n = len(mdh)
    mask = np.ones((n, 4), bool)
    mask[0] = False
    mask[-1, 2:] = False
    seconds, cpu_seconds, handler, nfev = [], [], None, 0
    for _ in range(int(data["repeats"])):
        robot = Robot.from_parameters(mdh.copy())
        robot.world_frame = data["world0"].copy()
        robot.tool.position = data["tool0"].copy()
        handler = OptimizationHandler(
            robot=robot,
            kinematic_chain_mask=mask.ravel().tolist(),
            tool_mask=[True, True, True, False, False, False],
            world_mask=[True] * 6,
        )
        t0, c0 = time.perf_counter(), time.process_time()
        res = scipy.optimize.least_squares(
            fun=optimize_accuracy,
            x0=handler.generate_optimization_vector(),
            args=(handler, data["q_train"], data["xyz_train"]),
        )
        handler.apply_optimization_vector(res.x)
        seconds.append(time.perf_counter() - t0)
        cpu_seconds.append(time.process_time() - c0)
        nfev = int(res.nfev)
    assert handler is not None
    pred = np.array([handler.robot.fk(q)[:3, 3] for q in data["q_test"]])
    np.savez(
        argv[1],
        pred_test=pred,
        seconds=np.array(seconds),
        cpu_seconds=np.array(cpu_seconds),
        nfev=nfev,
        version=version("pybotics"),
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

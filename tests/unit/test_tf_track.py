"""The transform tree over time (selfcal/ros/tf_track.py): edges interpolated between messages,
composed over several hops and through a common root, undefined outside the recording."""

from __future__ import annotations

from types import SimpleNamespace as NS_

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from selfcal.ros.bag_rest import NS
from selfcal.ros.tf_track import TfSeries
from selfcal.transforms import inv_pose, make_pose


def _msg(parent: str, child: str, T: np.ndarray, t: int):
    x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
    tr = NS_(header=NS_(frame_id=parent, stamp=NS_(sec=t // NS, nanosec=t % NS)),
             child_frame_id=child,
             transform=NS_(translation=NS_(x=T[0, 3], y=T[1, 3], z=T[2, 3]),
                           rotation=NS_(x=x, y=y, z=z, w=w)))  # fmt: skip
    return NS_(transforms=[tr])


def _pose(deg: float, x: float) -> np.ndarray:
    return make_pose(Rotation.from_euler("z", deg, degrees=True).as_matrix(), [x, 0.0, 0.5])


def test_a_moving_edge_is_interpolated_and_composed_with_the_static_ones():
    s = TfSeries("bag")
    tool = make_pose(Rotation.from_euler("x", 90, degrees=True).as_matrix(), [0, 0, 0.1])
    s.add(_msg("world", "base", _pose(10, 1.0), 0), static=True, stamp=0)
    s.add(_msg("link6", "tool0", tool, 0), static=True, stamp=0)
    for k, t in enumerate((NS, 2 * NS)):
        s.add(_msg("base", "link6", _pose(20 * k, 0.1 * k), t), static=False, stamp=t)
    T = s.lookup("base", "tool0", np.array([NS, 3 * NS // 2, 2 * NS, 3 * NS]))
    assert np.allclose(T[0], _pose(0, 0.0) @ tool) and np.allclose(T[2], _pose(20, 0.1) @ tool)
    assert np.allclose(T[1], _pose(10, 0.05) @ tool)  # halfway: slerp and lerp
    assert np.isnan(T[3]).all()  # after the last message: undefined, not held
    # through the common root: world -> tool0 and tool0 -> base agree with base -> tool0
    W = s.lookup("world", "tool0", np.array([NS]))[0]
    assert np.allclose(W, _pose(10, 1.0) @ T[0])
    assert np.allclose(s.lookup("tool0", "base", np.array([NS]))[0], inv_pose(T[0]))
    track = s.track("base", "tool0")
    assert len(track) == 2 and np.allclose(track.q[1, :3], (_pose(20, 0.1) @ tool)[:3, 3])


def test_frames_no_chain_joins_are_named():
    from selfcal.ros.rosbag import BagError

    s = TfSeries("rec.bag")
    s.add(_msg("base", "link6", _pose(0, 0), NS), static=False, stamp=NS)
    s.add(_msg("cam_rig", "camera", _pose(0, 0), NS), static=True, stamp=NS)
    with pytest.raises(BagError, match="no chain of transforms joins 'base' and 'camera'"):
        s.lookup("base", "camera", np.array([NS]))

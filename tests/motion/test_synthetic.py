"""The built-in demo clip: valid, grounded, smooth, and it actually moves every limb."""

from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS


def test_demo_motion_shapes_and_unit_quaternions() -> None:
    m = demo_motion(fps=30.0)
    assert m.num_frames == 361
    assert m.local_quats.shape == (361, 22, 4)
    np.testing.assert_allclose(np.linalg.norm(m.local_quats, axis=-1), 1.0, atol=1e-12)
    assert np.all(np.isfinite(m.root_pos))


def test_demo_motion_keeps_feet_on_or_above_the_ground() -> None:
    pos = demo_motion().positions()
    lowest = pos[:, :, 1].min(axis=1)
    assert lowest.min() > -1e-6  # nothing below the floor
    assert np.median(lowest) < 1e-3  # and standing on it most of the time


def test_demo_motion_is_smooth() -> None:
    m = demo_motion(fps=60.0)
    step = quat.angle_between(m.local_quats[1:], m.local_quats[:-1])
    # No joint turns faster than 15 rad/s (≈ 860 °/s): fast human motion, no jumps.
    assert step.max() * m.fps < 15.0


@pytest.mark.parametrize("joint", ["LeftArm", "RightArm", "RightForeArm", "LeftUpLeg", "RightLeg"])
def test_demo_motion_moves_each_limb(joint: str) -> None:
    q = demo_motion().local_quats[:, CANONICAL_JOINTS.index(joint)]
    assert np.degrees(quat.angle_between(q, q[:1]).max()) > 40.0


def test_demo_motion_rejects_bad_fps() -> None:
    with pytest.raises(ValueError, match="fps"):
        demo_motion(fps=0.0)

"""Virtual cameras and the canonical → COCO-17 projection used to train and evaluate."""

from __future__ import annotations

import math

import numpy as np

from robot_retarget.geometry import quaternion as quat
from robot_retarget.keypoints.coco17 import Coco
from robot_retarget.keypoints.synthetic import CLEAN, EstimatorNoise, render_keypoints
from robot_retarget.keypoints.virtual_camera import VirtualCamera, heading_quat
from robot_retarget.motion.synthetic import demo_motion


def test_performer_facing_the_camera_has_their_left_on_image_right() -> None:
    m = demo_motion(fps=30.0).frames(0, 5)
    cam = VirtualCamera(0.0, 0.0, 4.0, 1000.0)
    px, _conf, valid = render_keypoints(
        m.positions(), m.global_quats(), m.height_m, cam, np.random.default_rng(0), CLEAN
    )
    assert valid.all()
    assert (px[:, Coco.left_shoulder, 0] > px[:, Coco.right_shoulder, 0]).all()
    assert (px[:, Coco.nose, 1] < px[:, Coco.left_ankle, 1]).all()  # head above feet, y down


def test_heading_quat_turns_the_camera_to_azimuth_zero() -> None:
    a = math.radians(70.0)
    direction = np.array([math.sin(a), 0.0, math.cos(a)])
    np.testing.assert_allclose(quat.rotate(heading_quat(a), direction), [0, 0, 1], atol=1e-12)


def test_face_hidden_from_behind_and_noise_drops_points() -> None:
    m = demo_motion(fps=30.0).frames(0, 40)
    behind = VirtualCamera(math.pi, 0.0, 4.0, 1000.0)
    noise = EstimatorNoise(jitter=(0.0, 0.0), dropout=(0.0, 0.0), burst_probability=0.0,
                           face_hidden_probability=1.0)  # fmt: skip
    _px, _c, valid = render_keypoints(
        m.positions(), m.global_quats(), m.height_m, behind, np.random.default_rng(0), noise
    )
    assert not valid[:, Coco.nose].any()
    assert valid[:, Coco.left_hip].all()
    _px, conf, valid = render_keypoints(
        m.positions(), m.global_quats(), m.height_m, behind, np.random.default_rng(1),
        EstimatorNoise(dropout=(0.2, 0.2)),
    )  # fmt: skip
    assert 0.1 < 1 - valid.mean() < 0.6
    assert (conf[~valid] < 0.3).all()
    assert (conf[valid] >= 0.5).all()

"""Fixtures for the robot-side evaluation tests: OP3, its body model, poses, matching humans."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pytest

from robot_retarget.evaluation.robot.segments import SEGMENTS, RobotBodyModel
from robot_retarget.robot.canonical_skeleton import robot_canonical_skeleton
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.skeleton.canonical import Joint

FloatArray = npt.NDArray[np.float64]


@pytest.fixture(scope="session")
def op3() -> RobotConfig:
    return load_robot_config("op3")


@pytest.fixture(scope="session")
def op3_body(op3: RobotConfig) -> RobotBodyModel:
    return RobotBodyModel(op3)


def smooth_poses(config: RobotConfig, frames: int, seed: int = 0) -> FloatArray:
    """(T, J) smooth joint trajectories inside the limits: a slow sine per joint, 125 Hz."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None] / 125.0
    mid = 0.5 * (config.lower + config.upper)
    half = 0.45 * (config.upper - config.lower)
    phase = rng.uniform(0.0, 2.0 * np.pi, size=config.num_joints)
    freq = rng.uniform(0.3, 0.8, size=config.num_joints)
    return np.asarray(mid + half * np.sin(2.0 * np.pi * freq * t + phase), dtype=np.float64)


def human_like_robot(
    config: RobotConfig, body: RobotBodyModel, q: FloatArray, yaw_rad: float = 0.0
) -> FloatArray:
    """Canonical positions (T, 22, 3) of a human with the robot's proportions whose segments
    point exactly where the robot's do (built from the robot's body-frame directions), yawed by
    ``yaw_rad`` about the vertical and moved away from the origin."""
    d = body.body_points(q).directions  # (T, 9, 3) body frame: x fwd, y left, z up
    rest = robot_canonical_skeleton(config).rest_positions()  # canonical: X left, Y up, Z fwd
    length = {
        name: float(np.linalg.norm(rest[Joint[b]] - rest[Joint[a]]))
        for name, a, b in (
            ("upper_arm", "LeftArm", "LeftForeArm"),
            ("forearm", "LeftForeArm", "LeftHand"),
            ("thigh", "LeftUpLeg", "LeftLeg"),
            ("shin", "LeftLeg", "LeftFoot"),
        )
    }
    seg = {name: k for k, name in enumerate(SEGMENTS)}
    n = q.shape[0]
    body_pos = np.zeros((n, len(Joint), 3))
    hip_w, sho_w, torso = 0.035, 0.09, 0.14
    for side, sign in (("left", 1.0), ("right", -1.0)):
        cap = side.capitalize()
        body_pos[:, Joint[cap + "UpLeg"]] = (0.0, sign * hip_w, 0.0)
    shoulders = torso * d[:, seg["torso"]]
    for side, sign in (("left", 1.0), ("right", -1.0)):
        cap = side.capitalize()
        arm = shoulders + np.array([0.0, sign * sho_w, 0.0])
        body_pos[:, Joint[cap + "Arm"]] = arm
        elbow = arm + length["upper_arm"] * d[:, seg[f"{side}_upper_arm"]]
        body_pos[:, Joint[cap + "ForeArm"]] = elbow
        body_pos[:, Joint[cap + "Hand"]] = elbow + length["forearm"] * d[:, seg[f"{side}_forearm"]]
        hip = body_pos[:, Joint[cap + "UpLeg"]]
        knee = hip + length["thigh"] * d[:, seg[f"{side}_thigh"]]
        body_pos[:, Joint[cap + "Leg"]] = knee
        body_pos[:, Joint[cap + "Foot"]] = knee + length["shin"] * d[:, seg[f"{side}_shin"]]
    # Body (x fwd, y left, z up) → canonical (X left, Y up, Z fwd), then yaw about Y and shift.
    canon = body_pos[..., [1, 2, 0]]
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    yaw = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return np.asarray(canon @ yaw.T + np.array([0.7, 0.9, -1.3]), dtype=np.float64)


@pytest.fixture(scope="session")
def poses(op3: RobotConfig) -> FloatArray:
    """200 frames (1.6 s at 125 Hz) of smooth OP3 joint trajectories."""
    return smooth_poses(op3, 200)


@pytest.fixture(scope="session")
def human_for(op3: RobotConfig, op3_body: RobotBodyModel):  # type: ignore[no-untyped-def]
    """q (T, J), yaw → human canonical positions that reproduce the robot exactly."""

    def make(q: FloatArray, yaw_rad: float = 0.0) -> FloatArray:
        return human_like_robot(op3, op3_body, q, yaw_rad)

    return make

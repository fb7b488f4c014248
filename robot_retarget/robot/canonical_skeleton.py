"""The robot's proportions as the canonical 22-joint human skeleton (Y up, facing +Z, T-pose).

Networks retarget onto "the robot's skeleton": the canonical joints with the robot's bone lengths.
Lengths come from robot FK in the zero pose (a T-pose for the URDF conventions of OP3 and
Poppy) between the frames each bone of the config maps:

- limbs (upper arm, forearm, thigh, shin) lie along the canonical T-pose directions (arms ±X,
  legs −Y) with the robot's length;
- the torso (Hips → Neck) and the head (Neck → Head) point up (+Y) with the robot's length;
- hips (Hips → Left/RightUpLeg) and feet (Foot → ToeBase) keep the robot's own offset vector,
  rotated into canonical axes, so hip width and foot shape are the robot's;
- the arms start at the robot's shoulder points: Spine2 sits on the torso line at their mean
  height, Left/RightShoulder halfway from Spine2 to the arm, so the distance LeftArm ↔ RightArm
  is the robot's shoulder width; Spine and Spine1 split Hips → Spine2 in thirds.

Canonical axes from the config: X = left = up × forward, Y = up_axis, Z = forward_axis.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import ConfigError
from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS
from robot_retarget.skeleton.skeleton import Skeleton

# Bones every robot config must map for a canonical skeleton: (start joint, end joint).
REQUIRED_BONES: tuple[tuple[str, str], ...] = (
    ("Hips", "Neck"),
    ("Neck", "Head"),
    ("LeftArm", "LeftForeArm"),
    ("LeftForeArm", "LeftHand"),
    ("RightArm", "RightForeArm"),
    ("RightForeArm", "RightHand"),
    ("LeftUpLeg", "LeftLeg"),
    ("LeftLeg", "LeftFoot"),
    ("LeftFoot", "LeftToeBase"),
    ("RightUpLeg", "RightLeg"),
    ("RightLeg", "RightFoot"),
    ("RightFoot", "RightToeBase"),
)


def robot_to_canonical_rotation(config: RobotConfig) -> FloatArray:
    """Rotation (3, 3) taking root-link vectors to canonical axes (X left, Y up, Z forward)."""
    up = np.asarray(config.up_axis, dtype=np.float64)
    forward = np.asarray(config.forward_axis, dtype=np.float64)
    left = np.cross(up, forward)
    return np.stack([left, up, forward])


def bone_frame_positions(
    config: RobotConfig, q: npt.ArrayLike | None = None
) -> dict[tuple[str, str], tuple[FloatArray, FloatArray]]:
    """(start, end) positions (3,) in canonical axes of each mapped bone, keyed by its canonical
    (start, end) joints, at pose ``q`` (default: the zero pose)."""
    kin = RobotKinematics(config)
    q_arr = np.zeros(config.num_joints) if q is None else np.asarray(q, dtype=np.float64)
    rot = robot_to_canonical_rotation(config)
    out = {}
    for b in config.bones:
        p = kin.frame_positions(q_arr, [b.start_frame, b.end_frame]) @ rot.T
        out[(b.canonical, b.canonical_end)] = (p[0], p[1])
    return out


def check_required_bones(config: RobotConfig) -> None:
    """ConfigError naming the :data:`REQUIRED_BONES` that ``config`` does not map (the loader
    checks it, so that a config missing a bone is refused as it is read)."""
    mapped = {(b.canonical, b.canonical_end) for b in config.bones}
    missing = [f"{a}→{b}" for a, b in REQUIRED_BONES if (a, b) not in mapped]
    if missing:
        raise ConfigError(
            f"robot {config.name} maps no frames to the canonical bones {', '.join(missing)}; "
            "add them under 'bones' to build its canonical skeleton",
            path=config.source_path,
            key="bones",
            allowed=", ".join(f"{a}→{b}" for a, b in REQUIRED_BONES),
        )


def robot_canonical_skeleton(config: RobotConfig) -> Skeleton:
    """The canonical 22-joint skeleton with the robot's proportions (metres, T-pose)."""
    check_required_bones(config)
    bones = bone_frame_positions(config)

    def length(a: str, b: str) -> float:
        start, end = bones[(a, b)]
        return float(np.linalg.norm(end - start))

    def vector(a: str, b: str) -> FloatArray:
        start, end = bones[(a, b)]
        return end - start

    hips = bones[("Hips", "Neck")][0]
    x_axis, y_axis = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    pos: dict[str, FloatArray] = {"Hips": np.zeros(3)}
    pos["Neck"] = y_axis * length("Hips", "Neck")
    pos["Head"] = pos["Neck"] + y_axis * length("Neck", "Head")

    arm_l = bones[("LeftArm", "LeftForeArm")][0] - hips
    arm_r = bones[("RightArm", "RightForeArm")][0] - hips
    shoulder_height = float(np.clip(0.5 * (arm_l[1] + arm_r[1]), 0.0, pos["Neck"][1]))
    pos["Spine2"] = y_axis * shoulder_height
    pos["Spine"] = pos["Spine2"] / 3.0
    pos["Spine1"] = 2.0 * pos["Spine2"] / 3.0
    for side, arm, sign in (("Left", arm_l, 1.0), ("Right", arm_r, -1.0)):
        # The arm point keeps its lateral distance; height and depth follow the torso line.
        pos[f"{side}Arm"] = pos["Spine2"] + x_axis * arm[0]
        pos[f"{side}Shoulder"] = pos["Spine2"] + x_axis * (0.5 * arm[0])
        pos[f"{side}ForeArm"] = pos[f"{side}Arm"] + sign * x_axis * length(
            f"{side}Arm", f"{side}ForeArm"
        )
        pos[f"{side}Hand"] = pos[f"{side}ForeArm"] + sign * x_axis * length(
            f"{side}ForeArm", f"{side}Hand"
        )
        pos[f"{side}UpLeg"] = bones[(f"{side}UpLeg", f"{side}Leg")][0] - hips
        pos[f"{side}Leg"] = pos[f"{side}UpLeg"] - y_axis * length(f"{side}UpLeg", f"{side}Leg")
        pos[f"{side}Foot"] = pos[f"{side}Leg"] - y_axis * length(f"{side}Leg", f"{side}Foot")
        pos[f"{side}ToeBase"] = pos[f"{side}Foot"] + vector(f"{side}Foot", f"{side}ToeBase")

    offsets = np.zeros((len(CANONICAL_JOINTS), 3))
    for i, name in enumerate(CANONICAL_JOINTS):
        parent = CANONICAL_PARENTS[i]
        if parent >= 0:
            offsets[i] = pos[name] - pos[CANONICAL_JOINTS[parent]]
    return Skeleton(CANONICAL_JOINTS, CANONICAL_PARENTS, offsets)

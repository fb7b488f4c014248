"""The COCO-17 keypoint layout (COCO 2017 person keypoints; RTMPose, YOLO-pose and ViTPose
emit it in this order), and where each keypoint sits on the canonical skeleton.

Every keypoint format (OpenPose BODY_25 / COCO-18, MediaPipe Pose) is mapped onto these 17
points; the keypoint model consumes them.
"""

from __future__ import annotations

from enum import IntEnum

from robot_retarget.skeleton.canonical import Joint


class Coco(IntEnum):
    """COCO-17 keypoint indices, in the order of the COCO annotation files."""

    nose = 0
    left_eye = 1
    right_eye = 2
    left_ear = 3
    right_ear = 4
    left_shoulder = 5
    right_shoulder = 6
    left_elbow = 7
    right_elbow = 8
    left_wrist = 9
    right_wrist = 10
    left_hip = 11
    right_hip = 12
    left_knee = 13
    right_knee = 14
    left_ankle = 15
    right_ankle = 16


COCO17_NAMES: tuple[str, ...] = tuple(k.name for k in sorted(Coco, key=int))
NUM_KEYPOINTS = len(COCO17_NAMES)

# Body keypoints placed at a canonical joint (the joint where the bone starts).
BODY_JOINTS: dict[int, int] = {
    Coco.left_shoulder: Joint.LeftArm,
    Coco.right_shoulder: Joint.RightArm,
    Coco.left_elbow: Joint.LeftForeArm,
    Coco.right_elbow: Joint.RightForeArm,
    Coco.left_wrist: Joint.LeftHand,
    Coco.right_wrist: Joint.RightHand,
    Coco.left_hip: Joint.LeftUpLeg,
    Coco.right_hip: Joint.RightUpLeg,
    Coco.left_knee: Joint.LeftLeg,
    Coco.right_knee: Joint.RightLeg,
    Coco.left_ankle: Joint.LeftFoot,
    Coco.right_ankle: Joint.RightFoot,
}

# The limb bones between body keypoints: (joint, its child, keypoint at the joint, at the child).
LIMB_BONES: tuple[tuple[Joint, Joint, Coco, Coco], ...] = (
    (Joint.LeftArm, Joint.LeftForeArm, Coco.left_shoulder, Coco.left_elbow),
    (Joint.LeftForeArm, Joint.LeftHand, Coco.left_elbow, Coco.left_wrist),
    (Joint.RightArm, Joint.RightForeArm, Coco.right_shoulder, Coco.right_elbow),
    (Joint.RightForeArm, Joint.RightHand, Coco.right_elbow, Coco.right_wrist),
    (Joint.LeftUpLeg, Joint.LeftLeg, Coco.left_hip, Coco.left_knee),
    (Joint.LeftLeg, Joint.LeftFoot, Coco.left_knee, Coco.left_ankle),
    (Joint.RightUpLeg, Joint.RightLeg, Coco.right_hip, Coco.right_knee),
    (Joint.RightLeg, Joint.RightFoot, Coco.right_knee, Coco.right_ankle),
)

# Face keypoints in the Head joint's frame of a 1.7 m adult (metres; canonical rest: Y up,
# facing +Z, left = +X), scaled with the performer's height. Approximate anthropometry: the
# estimator's own noise is larger than their error.
FACE_OFFSETS_M: dict[int, tuple[float, float, float]] = {
    Coco.nose: (0.0, 0.08, 0.10),
    Coco.left_eye: (0.032, 0.11, 0.085),
    Coco.right_eye: (-0.032, 0.11, 0.085),
    Coco.left_ear: (0.075, 0.09, 0.0),
    Coco.right_ear: (-0.075, 0.09, 0.0),
}
FACE_KEYPOINTS: tuple[int, ...] = tuple(int(k) for k in FACE_OFFSETS_M)

# Left/right partners (for mirroring).
FLIP_PAIRS: tuple[tuple[int, int], ...] = tuple(
    (int(Coco[n]), int(Coco["right" + n[4:]])) for n in COCO17_NAMES if n.startswith("left")
)

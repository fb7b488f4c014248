"""The demo's 2D variant: the built-in routine as a camera would see it, lifted to 3D.

The built-in clip (robot_retarget.motion.synthetic) is projected through a virtual camera in
front of the performer (azimuth 30°, elevation 10°, 4 m, 1000 px) at 30 fps with
estimator-like noise (robot_retarget.keypoints.synthetic), and lifted by the keypoint model's
causal step, frame by frame as ``stream --source udp-keypoints://`` does. The lifted motion
then goes through the demo's offline conversion and live stream unchanged; the demo also
scores the robot against the routine's 3D ground truth.
"""

from __future__ import annotations

import math

import numpy as np

from robot_retarget.keypoints.lift import lift_keypoints
from robot_retarget.keypoints.sequence import KeypointSequence
from robot_retarget.keypoints.synthetic import EstimatorNoise, render_keypoints
from robot_retarget.keypoints.virtual_camera import VirtualCamera
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.runtime.agnostic2d import Agnostic2DRuntime

DEMO_CAMERA = VirtualCamera(math.radians(30.0), math.radians(10.0), 4.0, 1000.0)


def demo_keypoints(motion: HumanMotion, seed: int = 0) -> KeypointSequence:
    """``motion`` (30 fps) seen by :data:`DEMO_CAMERA` with estimator-like noise."""
    px, conf, valid = render_keypoints(
        motion.positions(), motion.global_quats(), motion.height_m, DEMO_CAMERA,
        np.random.default_rng(seed), EstimatorNoise(),
    )  # fmt: skip
    return KeypointSequence(
        px,
        conf,
        valid,
        motion.fps,
        source="built-in routine, 2D",
        image_size=DEMO_CAMERA.image_size,
    )


def demo_lifted_motion(motion: HumanMotion, model: Agnostic2DRuntime) -> HumanMotion:
    """The routine seen in 2D and lifted causally (see the module docstring)."""
    return lift_keypoints(demo_keypoints(motion), model, causal=True)

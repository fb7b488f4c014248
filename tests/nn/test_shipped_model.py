"""The shipped default checkpoint: what it is, what it was trained on, and that it still beats
copying the rotations where the README says it does."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robot_retarget.evaluation import metrics
from robot_retarget.evaluation.noise import corrupt
from robot_retarget.evaluation.skeleton_measures import skeleton_height
from robot_retarget.motion.human_motion import load_motion
from robot_retarget.nn import inference
from robot_retarget.nn.dataset import DEFAULT_VALIDATION_SUBJECTS, robot_skeletons
from robot_retarget.nn.inference import load_model, retarget_clip
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS
from robot_retarget.skeleton.skeleton import Skeleton, forward_kinematics

MAX_BYTES = 20 * 1024 * 1024


def test_default_checkpoint_ships_small_with_its_provenance() -> None:
    path = inference.shipped_checkpoints()[inference.DEFAULT_MODEL]
    assert path.stat().st_size < MAX_BYTES
    loaded = load_model(inference.DEFAULT_MODEL)
    assert loaded.architecture == "residual"
    meta = loaded.metadata
    assert "launch.py train --model residual" in meta["command"]
    assert set(meta["validation_subjects"]) == set(DEFAULT_VALIDATION_SUBJECTS)
    assert not set(meta["train_subjects"]) & set(DEFAULT_VALIDATION_SUBJECTS)
    assert "robot:op3" in loaded.skeletons


@pytest.mark.data
def test_default_beats_copy_on_an_unseen_subject_retargeted_to_op3(shared_data_dir: Path) -> None:
    """CMU 08_01 (subject 08, never trained on) onto OP3: smaller effector and contact error
    than copy, bone directions within 2°, and less sensitive to input noise than copy-scaled."""
    clip = load_motion(shared_data_dir / "mocap" / "08" / "08_01.bvh", max_frames=1200)
    motion = clip.resample(30.0)  # the rate the model was trained and evaluated at
    src = Skeleton(CANONICAL_JOINTS, CANONICAL_PARENTS, motion.skeleton.offsets)
    tgt = Skeleton(CANONICAL_JOINTS, CANONICAL_PARENTS, robot_skeletons(("op3",))["op3"])
    src_pos = forward_kinematics(src, motion.local_quats, motion.root_pos)[0]

    def run(name: str, quats: np.ndarray, root: np.ndarray) -> np.ndarray:
        q, r = retarget_clip(load_model(name), quats, root, src.offsets, tgt.offsets)
        return np.asarray(forward_kinematics(tgt, q, r)[0])

    scores = {}
    for name in ("copy-scaled", inference.DEFAULT_MODEL):
        pos = run(name, motion.local_quats, motion.root_pos)
        noisy = corrupt(
            motion.local_quats, motion.root_pos, motion.height_m, np.random.default_rng(0)
        )
        scores[name] = {
            "ee": metrics.end_effector_error(src_pos, src, pos, tgt),
            "contact": metrics.contact_distance_error(src_pos, src, pos, tgt),
            "bone": metrics.bone_direction_error_deg(src_pos, src, pos, tgt),
            "denoise": metrics.position_error(run(name, *noisy), pos, skeleton_height(tgt)),
        }
    ours, copy = scores[inference.DEFAULT_MODEL], scores["copy-scaled"]
    assert ours["ee"] < copy["ee"]
    assert ours["contact"] < copy["contact"]
    assert ours["bone"] < copy["bone"] + 2.0
    assert ours["denoise"] < copy["denoise"]

"""The shipped default checkpoint: what it is, what it was trained on, and that it still beats
copying the rotations where the README says it does."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robot_retarget.evaluation.folds import DEFAULT_FOLDS
from robot_retarget.evaluation.runner import EvalSettings, evaluate
from robot_retarget.motion.human_motion import load_motion
from robot_retarget.nn import inference
from robot_retarget.nn.dataset import Clip, robot_skeletons
from robot_retarget.nn.inference import load_model
from robot_retarget.nn.models.residual import ResidualRetargeter

MAX_BYTES = 20 * 1024 * 1024
# A 5° sideways knee bend may move another joint's correction by at most this much.
SENSITIVITY_LIMIT_DEG = 6.0  # measured 3.9° (shipped model), 21° before the fix


def test_default_checkpoint_ships_small_with_its_provenance() -> None:
    path = inference.shipped_checkpoints()[inference.DEFAULT_MODEL]
    assert path.stat().st_size < MAX_BYTES
    loaded = load_model(inference.DEFAULT_MODEL)
    assert loaded.architecture == "residual"
    meta = loaded.metadata
    assert "launch.py train --model residual" in meta["command"]
    # The cross-validation protocol's test-fold model: the test fold never seen, nothing picked.
    held_out = set(DEFAULT_FOLDS.test)
    assert set(meta["train_config"]["exclude_subjects"]) == held_out
    assert not set(meta["train_subjects"]) & held_out
    assert meta["validation_subjects"] == []
    assert meta["step"] == meta["train_config"]["steps"]
    assert "robot:op3" in loaded.skeletons
    assert loaded.model.config()["foot_lock"] is True


# Clips of the held-out test fold's performers (never trained on), first 10 s at 30 fps.
UNSEEN_CLIPS = (
    ("07", "07_01.bvh"), ("07", "07_06.bvh"), ("07", "07_12.bvh"),
    ("13", "13_10.bvh"), ("13", "13_32.bvh"), ("13", "13_41.bvh"),
)  # fmt: skip


@pytest.mark.data
def test_default_beats_copy_on_unseen_subjects_retargeted_to_op3(shared_data_dir: Path) -> None:
    """The eval runner on six unseen clips onto OP3: smaller effector and contact error than
    copy, bone directions within 2°, and less sensitive to input noise than copy-scaled."""
    clips = []
    for subject, name in UNSEEN_CLIPS:
        motion = load_motion(shared_data_dir / "mocap" / subject / name).resample(30.0)
        clips.append(
            Clip(name, subject, motion.local_quats[:300], motion.root_pos[:300],
                 motion.skeleton.offsets, 30.0, motion.height_m)
        )  # fmt: skip
    robots = robot_skeletons(("op3",))
    scores = {
        name: evaluate(load_model(name), clips, robots, EvalSettings()).by_target["robot"]
        for name in ("copy-scaled", inference.DEFAULT_MODEL)
    }
    ours, copy = scores[inference.DEFAULT_MODEL], scores["copy-scaled"]
    assert ours["ee"] < copy["ee"]
    assert ours["contact"] < copy["contact"]
    assert ours["bone_deg"] < copy["bone_deg"] + 2.0
    assert ours["denoise"] < copy["denoise"]


@pytest.mark.data
def test_default_is_not_hypersensitive_to_an_unusual_joint(shared_data_dir: Path) -> None:
    """Bending one knee 5° sideways (a pose the data never shows) must not swing the other
    joints' corrections around: before spread floors and the Δq cap, it moved the forearm's
    correction by 21°. The correction network is what is tested: the foot lock, whose leg IK
    answers a moved ankle by design, is switched off."""
    import torch

    from robot_retarget.geometry import quaternion as quat
    from robot_retarget.nn import quaternion_torch as qt
    from robot_retarget.nn.features import compute_features
    from robot_retarget.skeleton.canonical import Joint

    model = load_model(inference.DEFAULT_MODEL).model
    assert isinstance(model, ResidualRetargeter)
    model.lock = None
    motion = load_motion(shared_data_dir / "mocap" / "06" / "06_01.bvh", max_frames=400)
    motion = motion.resample(30.0)
    q = motion.local_quats.copy()
    bent = q.copy()
    side = quat.from_rotation_vector(np.array([0.0, 0.0, np.radians(5.0)]))
    bent[:, Joint.LeftLeg] = quat.mul(bent[:, Joint.LeftLeg], side)
    src = torch.tensor(motion.skeleton.offsets, dtype=torch.float32)[None]
    tgt = torch.tensor(robot_skeletons(("op3",))["op3"], dtype=torch.float32)[None]
    root = torch.tensor(motion.root_pos, dtype=torch.float32)[None]

    def corrections(quats: np.ndarray) -> torch.Tensor:
        feats = compute_features(torch.tensor(quats, dtype=torch.float32)[None], root, src)
        with torch.no_grad():
            pred = model.retarget(feats, src, tgt)
        return qt.mul(qt.conjugate(pred.extras["q_denoised"]), pred.local_quats)[0]

    change = np.degrees(qt.angle_between(corrections(q), corrections(bent)).numpy())
    others = [j for j in range(22) if j not in (Joint.LeftLeg, Joint.LeftFoot, Joint.LeftToeBase)]
    assert change[:, others].max() < SENSITIVITY_LIMIT_DEG

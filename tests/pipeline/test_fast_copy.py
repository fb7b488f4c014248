"""The numpy copy baselines equal the torch models' online step (to rounding)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.human_motion import HumanMotion, load_motion
from robot_retarget.nn.inference import LoadedModel, OnlineRetargeter, load_model
from robot_retarget.nn.models.copy import CopyModel
from robot_retarget.robot.canonical_skeleton import robot_canonical_skeleton
from robot_retarget.robot.config import RobotConfig
from robot_retarget.runtime.copy import (
    FastCopyRetargeter,
    rest_height_m,
)
from robot_retarget.runtime.loader import online_retargeter
from robot_retarget.skeleton.canonical import default_canonical_skeleton
from tests.pipeline.stream_equality import assert_same_stream, clear_of_half_turns

TOL = 1e-12
BASELINES = ("copy", "copy-scaled")


def _assert_same_stream(
    model: LoadedModel, src: np.ndarray, tgt: np.ndarray, quats: np.ndarray, root: np.ndarray
) -> None:
    assert_same_stream(model, src, tgt, quats, root, FastCopyRetargeter, TOL)


@pytest.mark.parametrize("name", BASELINES)
def test_equals_the_torch_model_on_the_demo(name: str, demo: HumanMotion, op3: RobotConfig) -> None:
    tgt = robot_canonical_skeleton(op3).offsets
    _assert_same_stream(
        load_model(name), demo.skeleton.offsets, tgt, demo.local_quats, demo.root_pos
    )


# CMU 02_01 (a walk) and 05_14, whose heading wraps through ±π at frame 23 (first frames).
REAL_CLIPS = (("02", "02_01.bvh", 200), ("05", "05_14.bvh", 120))


@pytest.mark.data
@pytest.mark.parametrize("clip", REAL_CLIPS)
@pytest.mark.parametrize("name", BASELINES)
def test_equals_the_torch_model_on_real_mocap(
    name: str, clip: tuple[str, str, int], shared_data_dir: Path, op3: RobotConfig
) -> None:
    folder, file, frames = clip
    motion = load_motion(shared_data_dir / "mocap" / folder / file, max_frames=frames)
    tgt = robot_canonical_skeleton(op3).offsets
    _assert_same_stream(
        load_model(name), motion.skeleton.offsets, tgt, motion.local_quats, motion.root_pos
    )


@settings(max_examples=20, deadline=None)
@given(
    arrays(np.float64, (6, 22, 3), elements=st.floats(-3.1, 3.1)),
    arrays(np.float64, (6, 3), elements=st.floats(-5.0, 5.0)),
    st.sampled_from(BASELINES),
)
def test_equals_the_torch_model_on_wild_streams(
    rotvecs: np.ndarray, root: np.ndarray, name: str
) -> None:
    """Arbitrary rotations and jumps: heading differences wrap the same way in both."""
    src = default_canonical_skeleton().offsets
    quats = quat.from_rotation_vector(rotvecs)
    assume(clear_of_half_turns(quats))
    _assert_same_stream(load_model(name), src, 0.4 * src, quats, root)


def test_scaled_root_moves_by_the_height_ratio(demo: HumanMotion) -> None:
    src = demo.skeleton.offsets
    plain = online_retargeter(load_model("copy"), src, 0.5 * src)
    scaled = online_retargeter(load_model("copy-scaled"), src, 0.5 * src)
    assert isinstance(scaled, FastCopyRetargeter)
    np.testing.assert_allclose(scaled.velocity_scale, 0.5, rtol=1e-12)
    q0, r0 = demo.local_quats[0], demo.root_pos[0]
    q1, r1 = demo.local_quats[10], demo.root_pos[10]
    plain.step(q0, r0)
    scaled.step(q0, r0)
    _, p_plain = plain.step(q1, r1)
    _, p_scaled = scaled.step(q1, r1)
    np.testing.assert_allclose(p_plain, r1, atol=1e-12)  # copy keeps the root path
    np.testing.assert_allclose(p_scaled - r0, 0.5 * (r1 - r0), atol=1e-12)


def test_rest_height_is_the_vertical_extent() -> None:
    skeleton = default_canonical_skeleton()
    pos = skeleton.rest_positions()
    assert rest_height_m(skeleton.offsets) == pytest.approx(np.ptp(pos[:, 1]), abs=1e-15)


def test_only_the_exact_baselines_take_the_fast_path(demo: HumanMotion) -> None:
    class Tweaked(CopyModel):  # a subclass may change the semantics
        name = "tweaked"

    src = demo.skeleton.offsets
    assert load_model("copy").model.runtime() is not None
    assert load_model("copy-scaled").model.runtime() is not None
    assert Tweaked().runtime() is None
    assert isinstance(online_retargeter(Tweaked(), src, src), OnlineRetargeter)


def test_wrong_shapes_raise_like_the_torch_step(demo: HumanMotion) -> None:
    src = demo.skeleton.offsets
    fast = online_retargeter(load_model("copy-scaled"), src, src)
    with pytest.raises(ValueError, match="local_quats"):
        fast.step(np.zeros((21, 4)), np.zeros(3))
    with pytest.raises(ValueError, match="root_pos"):
        fast.step(demo.local_quats[0], np.zeros(2))
    with pytest.raises(ValueError, match="source_offsets"):
        online_retargeter(load_model("copy-scaled"), src[:5], src)


def test_inputs_are_not_modified(demo: HumanMotion) -> None:
    fast = online_retargeter(load_model("copy"), demo.skeleton.offsets, demo.skeleton.offsets)
    quats = demo.local_quats[5].copy()
    fast.step(quats, demo.root_pos[5])
    out, _ = fast.step(quats, demo.root_pos[6])
    np.testing.assert_array_equal(quats, demo.local_quats[5])
    assert out is not quats

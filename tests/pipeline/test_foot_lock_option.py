"""The residual network's foot lock on the robot: left out unless asked (``--foot-lock``),
refused by models without one, and only ever the legs' business."""

from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.errors import ModelLoadError
from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.nn.inference import load_model
from robot_retarget.optimize import Retargeter
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.canonical_skeleton import robot_canonical_skeleton
from robot_retarget.robot.config import RobotConfig
from robot_retarget.runtime.loader import check_foot_lock, load_runtime_model, online_retargeter
from robot_retarget.runtime.model import OnlineStep, RuntimeModel
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS

LEG_JOINTS = {i for i, name in enumerate(CANONICAL_JOINTS) if "Leg" in name or "Foot" in name}


def _play(online: OnlineStep, motion: HumanMotion) -> np.ndarray:
    frames = range(motion.num_frames)
    return np.array([online.step(motion.local_quats[i], motion.root_pos[i])[0] for i in frames])


@pytest.fixture(scope="module")
def default() -> RuntimeModel:
    model = load_runtime_model("default")
    assert isinstance(model, RuntimeModel)
    return model


def test_the_lock_moves_only_the_legs_and_none_runs_the_model_as_exported(
    default: RuntimeModel, op3: RobotConfig, demo: HumanMotion
) -> None:
    assert default.has_foot_lock
    src, tgt = demo.skeleton.offsets, robot_canonical_skeleton(op3).offsets
    exported = _play(default.online(src, tgt), demo)
    locked = _play(default.online(src, tgt, foot_lock=True), demo)
    free = _play(default.online(src, tgt, foot_lock=False), demo)
    np.testing.assert_array_equal(exported, locked)
    moved = {int(j) for j in np.nonzero(np.abs(free - locked).max(axis=(0, 2)) > 1e-6)[0]}
    assert moved, "the demo walk plants its feet: the lock must engage somewhere"
    assert moved <= LEG_JOINTS, sorted(moved)
    # The torch model's live step leaves it out the same way.
    torch_free = _play(online_retargeter(load_model("default"), src, tgt, foot_lock=False), demo)
    np.testing.assert_allclose(torch_free, free, atol=1e-6)


def test_the_robot_path_leaves_the_lock_out_unless_asked(
    default: RuntimeModel, op3: RobotConfig, retargeter: Retargeter, demo: HumanMotion
) -> None:
    src, tgt = demo.skeleton.offsets, robot_canonical_skeleton(op3).offsets
    rate = op3.control_rate_hz
    plain = RetargetStep(op3, "default", demo.skeleton, retargeter=retargeter)
    asked = RetargetStep(op3, "default", demo.skeleton, retargeter=retargeter, foot_lock=True)
    np.testing.assert_array_equal(
        _play(plain.online, demo),
        _play(default.online(src, tgt, frame_rate_hz=rate, foot_lock=False), demo),
    )
    np.testing.assert_array_equal(
        _play(asked.online, demo), _play(default.online(src, tgt, frame_rate_hz=rate), demo)
    )


@pytest.mark.parametrize("name", ["copy", "copy-scaled"])
def test_a_lock_asked_of_a_model_without_one_is_refused(
    name: str, op3: RobotConfig, retargeter: Retargeter, demo: HumanMotion
) -> None:
    model = load_runtime_model(name)
    check_foot_lock(model, foot_lock=False)  # not asked: nothing to refuse
    with pytest.raises(ModelLoadError, match=f"'{name}' has no foot lock") as err:
        check_foot_lock(model, foot_lock=True)
    assert err.value.model == name
    with pytest.raises(ModelLoadError, match="leave out --foot-lock"):
        RetargetStep(op3, name, demo.skeleton, retargeter=retargeter, foot_lock=True)


class _BuiltError(Exception):
    """Raised by the recording stand-in once the entry point has built its step."""


@pytest.fixture
def built(monkeypatch: pytest.MonkeyPatch) -> list[bool]:
    """Every robot entry point builds a RetargetStep: record the foot lock it asks for and stop
    there (nothing is solved)."""
    import robot_retarget.api
    import robot_retarget.evaluation.robustness
    import robot_retarget.pipeline.step

    calls: list[bool] = []

    def record(*_args: object, foot_lock: bool = False, **_kwargs: object) -> None:
        calls.append(foot_lock)
        raise _BuiltError

    for module in (robot_retarget.pipeline.step, robot_retarget.api,
                   robot_retarget.evaluation.robustness):  # fmt: skip
        monkeypatch.setattr(module, "RetargetStep", record)
    return calls


@pytest.mark.parametrize("asked", [False, True])
def test_every_robot_entry_point_forwards_the_choice(
    asked: bool, built: list[bool], op3: RobotConfig, demo: HumanMotion
) -> None:
    import argparse
    from pathlib import Path

    from robot_retarget.api import retarget
    from robot_retarget.evaluation.robot.runner import pipeline_runner
    from robot_retarget.evaluation.robustness import robustness
    from robot_retarget.pipeline import benchmark
    from robot_retarget.pipeline.clip_converter import ClipConverter, ConvertOptions

    clip = Path(__file__).resolve().parents[1] / "fixtures" / "motion" / "tiny_walk.bvh"
    parser = argparse.ArgumentParser()
    benchmark.configure(parser)
    entry_points = [
        lambda: retarget(demo, op3, foot_lock=asked),
        lambda: pipeline_runner(op3, "default", foot_lock=asked)(demo),
        lambda: robustness(
            op3, [("t", clip)], ["default"], (), foot_lock_models=["default"] if asked else []
        ),
        lambda: ClipConverter(ConvertOptions("op3", "default", foot_lock=asked)),
        lambda: benchmark.run(parser.parse_args(["--foot-lock"] if asked else [])),
    ]
    for enter in entry_points:
        with pytest.raises(_BuiltError):
            enter()
    assert built == [asked] * len(entry_points)

"""Optimizer options from a robot config's ``retarget`` section."""

from __future__ import annotations

import math

import pytest

from robot_retarget.errors import ConfigError
from robot_retarget.robot.retarget_settings import RetargetSettings

BONES = ("LeftArm", "LeftForeArm")


def test_defaults() -> None:
    s = RetargetSettings.from_mapping({}, bone_names=BONES)
    assert s == RetargetSettings()
    assert s.twist_limit_rad("LeftArm") == pytest.approx(math.radians(100.0))


def test_values_and_per_bone_twist_override() -> None:
    s = RetargetSettings.from_mapping(
        {"w_direction": 2.0, "window": 8, "overlap": 1, "twist_limit_deg.LeftForeArm": 120},
        bone_names=BONES,
    )
    assert s.w_direction == 2.0
    assert (s.window, s.overlap) == (8, 1)
    assert s.twist_limit_rad("LeftForeArm") == pytest.approx(math.radians(120.0))
    assert s.twist_limit_rad("LeftArm") == pytest.approx(math.radians(100.0))


def test_unknown_key_names_key_and_allowed_keys() -> None:
    with pytest.raises(ConfigError) as err:
        RetargetSettings.from_mapping({"w_dirction": 1.0}, bone_names=BONES, path="op3.yaml")
    assert err.value.key == "retarget.w_dirction"
    assert err.value.path == "op3.yaml"
    assert err.value.allowed is not None
    assert "w_direction" in err.value.allowed
    assert "twist_limit_deg.LeftForeArm" in err.value.allowed


def test_twist_override_for_unmapped_bone_is_unknown() -> None:
    with pytest.raises(ConfigError, match="unknown"):
        RetargetSettings.from_mapping({"twist_limit_deg.RightArm": 90}, bone_names=BONES)


@pytest.mark.parametrize(
    ("values", "key"),
    [
        ({"w_velocity": -1.0}, "retarget.w_velocity"),
        ({"w_init": math.nan}, "retarget.w_init"),
        ({"w_init": "0.1"}, "retarget.w_init"),
        ({"w_init": True}, "retarget.w_init"),
        ({"window": 1}, "retarget.window"),
        ({"window": 8, "overlap": 8}, "retarget.overlap"),
        ({"window": 8.5}, "retarget.window"),
        ({"max_iter": 0}, "retarget.max_iter"),
        ({"warm_start_step": -0.5}, "retarget.warm_start_step"),
        ({"step_tol_ticks": -0.1}, "retarget.step_tol_ticks"),
    ],
)
def test_invalid_values(values: dict[str, object], key: str) -> None:
    with pytest.raises(ConfigError) as err:
        RetargetSettings.from_mapping(values, bone_names=BONES)  # type: ignore[arg-type]
    assert err.value.key == key


def test_per_bone_weights_and_foot_defaults() -> None:
    bones = ("LeftArm", "LeftFoot", "RightFoot")
    s = RetargetSettings.from_mapping(
        {"w_direction": 2.0, "w_direction.LeftArm": 0.5, "w_orientation.LeftFoot": 0.0},
        bone_names=bones,
    )
    assert s.direction_weight("LeftArm") == 0.5
    assert s.direction_weight("LeftForeArm") == 2.0  # unmapped bones take the default
    # A foot's direction is weighted 0.02 unless the robot says otherwise.
    assert s.direction_weight("LeftFoot") == s.direction_weight("RightFoot") == 0.02
    assert s.orientation_weight("LeftFoot") == 0.0
    assert s.orientation_weight("LeftArm") == s.w_orientation
    feet = RetargetSettings.from_mapping({"w_direction.LeftFoot": 1.0}, bone_names=bones)
    assert feet.direction_weight("LeftFoot") == 1.0
    assert feet.direction_weight("RightFoot") == 0.02


@pytest.mark.parametrize(
    "key", ["w_direction.Hips", "w_orientation.LeftArm.x", "w_keypoint.LeftArm", "direction_eps.X"]
)
def test_per_bone_keys_need_a_mapped_bone_and_a_per_bone_option(key: str) -> None:
    with pytest.raises(ConfigError, match="unknown") as err:
        RetargetSettings.from_mapping({key: 1.0}, bone_names=BONES)
    assert err.value.key == f"retarget.{key}"
    assert err.value.allowed is not None
    assert "w_direction.LeftForeArm" in err.value.allowed


def test_new_scalars_are_validated() -> None:
    s = RetargetSettings.from_mapping({"direction_eps": 0.1, "w_keypoint": 20}, bone_names=BONES)
    assert (s.direction_eps, s.w_keypoint) == (0.1, 20.0)
    with pytest.raises(ConfigError):
        RetargetSettings.from_mapping({"direction_eps": -0.1}, bone_names=BONES)

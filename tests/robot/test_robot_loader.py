"""Config loader: real configs load, every kind of mistake is a ConfigError naming file and key."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.errors import ConfigError
from robot_retarget.robot import loader
from robot_retarget.robot.loader import (
    available_robots,
    load_robot_config,
    parse_robot_config,
    resolve_config_path,
)

R_SHO_PITCH_LIMITS = "limits: {lower: !deg -90, upper: !deg 90, velocity: !rpm 46}"

# (what is wrong, text to replace (first occurrence), replacement, expected key, message part)
MISTAKES = [
    ("unknown top key", "root_link: body_link\n", "root_link: body_link\ncolour: red\n",
     "colour", "unknown key"),
    ("missing key", "root_link: body_link\n", "", "root_link", "missing key"),
    ("wrong type", "baud_rate: 2000000", "baud_rate: fast", "buses[0].baud_rate", "integer"),
    ("lower >= upper", R_SHO_PITCH_LIMITS,
     "limits: {lower: !deg 90, upper: !deg -90, velocity: !rpm 46}",
     "joints[0].limits.lower", "must be below upper"),
    ("limit outside servo range", R_SHO_PITCH_LIMITS,
     "limits: {lower: !deg -200, upper: !deg 90, velocity: !rpm 46}",
     "joints[0].limits.lower", "outside what the XM430-W350 reaches"),
    ("duplicate servo id", "servo: {id: 2,", "servo: {id: 1,", "joints[1].servo.id",
     "already used"),
    ("duplicate joint name", "- name: l_sho_pitch", "- name: r_sho_pitch", "joints[1].name",
     "duplicate joint name"),
    ("unknown servo model", "model: XM430-W350", "model: XM999", "joints[0].servo.model",
     "unknown servo model"),
    ("model/protocol mismatch", "protocol: 2.0", "protocol: 1.0", "joints[0].servo.model",
     "and bus 'main' is Protocol 1.0"),
    ("unknown protocol", "protocol: 2.0", "protocol: 3.0", "buses[0].protocol",
     "unknown protocol"),
    ("unknown bus", "bus: main, direction: 1", "bus: aux, direction: 1",
     "joints[0].servo.bus", "no bus named 'aux'"),
    ("unknown parent link", "parent_link: r_sho_pitch_link", "parent_link: nowhere",
     "joints[2].parent_link", "unknown link 'nowhere'"),
    ("cycle", "parent_link: body_link\n    child_link: r_sho_pitch_link",
     "parent_link: r_el_link\n    child_link: r_sho_pitch_link", "joints[0].parent_link",
     "cycle"),
    ("bad direction", "direction: 1,", "direction: 2,", "joints[0].servo.direction", "got 2"),
    ("zero axis", "axis: [0, -1, 0]", "axis: [0, 0, 0]", "joints[0].axis", "non-zero"),
    ("init pose outside limits", "  l_knee: !deg 142", "  l_knee: !deg 170", "init_pose.l_knee",
     "outside the joint limits"),
    ("init pose misses a joint", "  head_tilt: !deg -10\n", "", "init_pose.head_tilt",
     "missing key"),
    ("safe pose names an unknown joint", "safe_pose:\n", "safe_pose:\n  tail: 0.0\n",
     "safe_pose.tail", "unknown key"),
    ("bone to unknown frame", "end: l_hand}", "end: l_palm}", "bones[3].end",
     "unknown frame 'l_palm'"),
    ("bone with unknown canonical joint", "canonical: LeftArm,", "canonical: LeftWing,",
     "bones[2].canonical", "unknown canonical joint"),
    ("bone against the canonical tree", "canonical: LeftArm, canonical_end: LeftForeArm",
     "canonical: LeftForeArm, canonical_end: LeftArm", "bones[2].canonical_end",
     "does not lie below"),
    ("velocity above no-load speed", "velocity: !rpm 46}", "velocity: !rpm 60}",
     "joints[0].limits.velocity", "no-load speed"),
    ("velocity zero", "velocity: !rpm 46}", "velocity: 0}", "joints[0].limits.velocity",
     "must be > 0"),
    ("forward not perpendicular to up", "forward_axis: [1, 0, 0]", "forward_axis: [1, 0, 1]",
     "forward_axis", "perpendicular"),
    ("frame on an unknown link", "parent_link: l_el_link, origin: {xyz: [0.0, 0.15",
     "parent_link: l_wrist_link, origin: {xyz: [0.0, 0.15", "frames[2].parent_link",
     "unknown link"),
    ("odd return delay", "return_delay_us: 0", "return_delay_us: 3",
     "hardware.return_delay_us", "got 3"),
    ("baud rate no servo runs at", "baud_rate: 2000000", "baud_rate: 2000001",
     "buses[0].baud_rate", "not a rate Protocol 2.0 servos can be set to"),
    ("control rate beyond a bus", "control_rate_hz: 125", "control_rate_hz: 100000",
     "control_rate_hz", "more than a Dynamixel bus serves"),
    ("profile velocity above every servo's speed", "profile_velocity_rad_s: 4.0",
     "profile_velocity_rad_s: 40", "hardware.profile_velocity_rad_s",
     "would limit nothing"),
    ("a limit written as a speed", R_SHO_PITCH_LIMITS,
     "limits: {lower: !rpm -10, upper: !deg 90, velocity: !rpm 46}",
     "joints[0].limits.lower", "written with !rpm"),
    ("zero offset in degrees", "direction: 1, zero_offset: 0.0}",
     "direction: 1, zero_offset: 10}",
     "joints[0].servo.zero_offset", "more than half a turn"),
    ("root link no joint hangs from", "root_link: body_link", "root_link: base_link",
     "root_link", "no joint hangs from 'base_link'"),
    # Geometry at the zero pose (robot/bone_geometry.py): each a robot that would stand still.
    ("forward axis reversed", "forward_axis: [1, 0, 0]", "forward_axis: [-1, 0, 0]",
     "forward_axis", "forward_axis or up_axis points the wrong way"),
    ("forward axis turned 90°", "forward_axis: [1, 0, 0]", "forward_axis: [0, 1, 0]",
     "bones[2]", "lies on the robot's right"),
    ("forearm start and end swapped", "start: l_el_link, end: l_hand}",
     "start: l_hand, end: l_el_link}", "bones[3]", "runs backwards: its end, not its start"),
    ("upper arm start and end swapped", "start: l_sho_roll_link, end: l_el_link}",
     "start: l_el_link, end: l_sho_roll_link}", "bones[2]",
     "runs backwards: LeftForeArm starts at its start"),
    ("left upper arm on the right arm's links", "start: l_sho_roll_link, end: l_el_link}",
     "start: r_sho_roll_link, end: r_el_link}", "bones[2]",
     "LeftArm (r_sho_roll_link → r_el_link) lies on the robot's right"),
    ("a forearm that starts where the upper arm starts", "start: l_el_link, end: l_hand}",
     "start: l_sho_roll_link, end: l_hand}", "bones[3].start",
     "starts where LeftArm (l_sho_roll_link → l_el_link) starts, not where it ends"),
    ("left forearm ending at the right hand", "start: l_el_link, end: l_hand}",
     "start: l_el_link, end: r_hand}", "bones[3]", "lies on the robot's right"),
    ("a bone that does not join its parent", "start: l_ankle_center, end: l_toe}",
     "start: l_hip_center, end: l_toe}", "bones[8].start", "a limb's bones join end to start"),
    ("an option written as a switch", "retarget:\n", "retarget:\n  level_feet: true\n",
     "retarget.level_feet", "got True: write 1 instead"),
    # The optimizer's section is checked as the file is read (load_robot had taken these).
    ("a misspelt optimizer option", "retarget:\n", "retarget:\n  w_orientaton: 0.01\n",
     "retarget.w_orientaton", "did you mean 'w_orientation'?"),
    ("a negative weight", "retarget:\n", "retarget:\n  w_direction: -1\n",
     "retarget.w_direction", "must be finite and ≥ 0"),
    ("an iteration count that is no whole number", "retarget:\n", "retarget:\n  max_iter: 2.5\n",
     "retarget.max_iter", "must be a whole number"),
]  # fmt: skip


def _write(tmp_path: Path, text: str, name: str = "robot.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("old", "new", "key", "message"),
    [m[1:] for m in MISTAKES],
    ids=[m[0] for m in MISTAKES],
)
def test_mistake_names_file_and_key(
    tmp_path: Path, op3_text: str, old: str, new: str, key: str, message: str
) -> None:
    assert old in op3_text, f"fixture text {old!r} no longer in op3.yaml"
    path = _write(tmp_path, op3_text.replace(old, new, 1))
    with pytest.raises(ConfigError) as info:
        load_robot_config(path)
    err = info.value
    assert err.key == key, str(err)
    assert err.path == str(path)
    assert message in str(err)
    assert str(path) in str(err)
    assert f"'{key}'" in str(err)
    own_field = (".limits.", ".servo.model", ".servo.bus", ".servo.direction")
    if key.startswith("joints[") and any(f in key for f in own_field):  # the joint is named
        index = int(key[len("joints[") : key.index("]")])
        assert f"(joint {load_robot_config('op3').joints[index].name!r})" in str(err)


def test_unknown_key_lists_allowed_keys(tmp_path: Path, op3_text: str) -> None:
    path = _write(tmp_path, op3_text.replace("protocol: 2.0", "protocol: 2.0\n    parity: odd", 1))
    with pytest.raises(ConfigError) as info:
        load_robot_config(path)
    assert info.value.key == "buses[0].parity"
    assert info.value.allowed == "name, protocol, baud_rate, default_port"


def test_unknown_model_lists_models(tmp_path: Path, op3_text: str) -> None:
    path = _write(tmp_path, op3_text.replace("model: XM430-W350", "model: XL320", 1))
    with pytest.raises(ConfigError) as info:
        load_robot_config(path)
    assert info.value.allowed == "AX-12A, MX-28, MX-64, XM430-W350"


def test_yaml_syntax_error_names_line(tmp_path: Path, op3_text: str) -> None:
    lines = op3_text.splitlines()
    bad_line = lines.index("control_rate_hz: 125")
    lines[bad_line] = "control_rate_hz: [125"
    path = _write(tmp_path, "\n".join(lines))
    with pytest.raises(ConfigError, match=r"YAML syntax error at line \d+") as info:
        load_robot_config(path)
    assert info.value.path == str(path)


def test_duplicate_yaml_key_is_an_error(tmp_path: Path, op3_text: str) -> None:
    text = op3_text.replace("control_rate_hz: 125", "control_rate_hz: 125\ncontrol_rate_hz: 100")
    with pytest.raises(ConfigError, match="duplicate key 'control_rate_hz'"):
        load_robot_config(_write(tmp_path, text))


def test_unit_tags_and_axis_normalisation(tmp_path: Path, op3_text: str) -> None:
    text = op3_text.replace("axis: [0, -1, 0]", "axis: [0, -2, 0]", 1)
    config = load_robot_config(_write(tmp_path, text))
    r = config.joints[0]
    assert r.axis == (0.0, -1.0, 0.0)
    assert r.lower_rad == pytest.approx(-math.pi / 2)
    assert r.max_velocity_rad_s == pytest.approx(46.0 * 2.0 * math.pi / 60.0)
    assert config.init_pose[config.joint_index("l_knee")] == pytest.approx(math.radians(142))


def test_bad_unit_tag_value(tmp_path: Path, op3_text: str) -> None:
    text = op3_text.replace("l_knee: !deg 142", "l_knee: !deg knee", 1)
    with pytest.raises(ConfigError, match=r"line \d+.*!deg needs a number, got 'knee'"):
        load_robot_config(_write(tmp_path, text))


def test_unknown_robot_lists_available() -> None:
    with pytest.raises(ConfigError) as info:
        load_robot_config("no_such_robot")
    assert "op3" in str(info.value.allowed)
    assert "poppy_humanoid" in str(info.value.allowed)


def test_missing_file_is_config_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not found"):
        load_robot_config(tmp_path / "nope.yaml")


def test_available_robots_and_resolution(config_dir: Path) -> None:
    names = available_robots()
    assert {"op3", "poppy_humanoid"} <= set(names)
    op3_file = config_dir / "op3" / "op3.yaml"
    assert resolve_config_path("op3") == op3_file
    assert resolve_config_path(str(op3_file)) == op3_file


def test_env_dir_is_searched_first(
    tmp_path: Path, op3_text: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    _write(tmp_path, op3_text.replace("name: op3\n", "name: my_op3\n", 1), name="op3.yaml")
    monkeypatch.setenv(loader.CONFIG_DIR_ENV, os.fspath(tmp_path))
    assert load_robot_config("op3").name == "my_op3"


def test_parse_from_text_and_frozen_poses(op3_text: str) -> None:
    config = parse_robot_config(op3_text)
    assert config.source_path is None
    assert config.name == "op3"
    with pytest.raises(ValueError, match="read-only"):
        config.init_pose[0] = 1.0
    np.testing.assert_array_equal(config.lower < config.upper, True)


def test_numbers_written_as_yaml_1_2_does() -> None:
    """1e-8 is a number (YAML 1.2; PyYAML's 1.1 rules read it as a string), and an unknown
    optimizer option suggests the nearest known one."""
    import yaml

    from robot_retarget.robot.retarget_settings import RetargetSettings

    doc = yaml.load("a: 1e-8\nb: -4E+2\nc: 12\nd: e5\n", Loader=loader._ConfigLoader)
    assert doc == {"a": 1e-8, "b": -400.0, "c": 12, "d": "e5"}
    with pytest.raises(ConfigError, match=r"did you mean 'w_acceleration'\?"):
        RetargetSettings.from_mapping({"w_acceleraton": 1.0})


def test_protocol_1_baud_rates_follow_the_servos_formula() -> None:
    from robot_retarget.robot.servo_models import baud_supported

    for baud in (1_000_000, 500_000, 115_200, 57_600, 9_600, 3_000_000):
        assert baud_supported(1.0, baud), baud
    for baud in (1_500_000, 5_000_000, 0):
        assert not baud_supported(1.0, baud), baud
    assert baud_supported(2.0, 4_000_000)
    assert not baud_supported(2.0, 500_000)


def test_a_robot_folder_and_a_tilde_find_its_file(
    tmp_path: Path, op3_text: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = tmp_path / "my_op3"
    folder.mkdir()
    _write(folder, op3_text, name="my_op3.yaml")
    assert load_robot_config(folder).source_path == str(folder / "my_op3.yaml")
    monkeypatch.setenv("HOME", os.fspath(tmp_path))
    assert load_robot_config("~/my_op3").source_path == str(folder / "my_op3.yaml")
    monkeypatch.setenv(loader.CONFIG_DIR_ENV, "~")
    assert load_robot_config("my_op3").source_path == str(folder / "my_op3.yaml")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ConfigError, match=r"a folder, without empty\.yaml in it"):
        load_robot_config(tmp_path / "empty")


def test_an_unknown_name_lists_the_folders_searched_that_exist(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A folder that is not there (a wheel's package data in a checkout, a stale env entry)
    would send the user looking in it: only folders that exist are listed."""
    gone = tmp_path / "gone"
    monkeypatch.setenv(loader.CONFIG_DIR_ENV, os.fspath(gone))
    with pytest.raises(ConfigError, match="no robot config named 'nao'") as info:
        load_robot_config("nao")
    text = str(info.value)
    assert str(gone) not in text
    assert all(Path(d).is_dir() for d in text.split("(searched ")[1].split(")")[0].split(", "))
    assert f"add its folder to {loader.CONFIG_DIR_ENV}" in text
    assert "allowed: op3, poppy_humanoid" in text


def test_a_config_missing_a_required_bone_is_refused_as_it_is_read(
    tmp_path: Path, op3_text: str
) -> None:
    """It loaded, and convert failed later (the README says all twelve are required and the
    loader names the key)."""
    line = "  - {canonical: Neck, canonical_end: Head, start: head_pan_link, end: head_point}\n"
    assert line in op3_text
    path = _write(tmp_path, op3_text.replace(line, "", 1))
    with pytest.raises(ConfigError, match=r"key 'bones'.*canonical bones Neck→Head") as info:
        load_robot_config(path)
    assert info.value.key == "bones"

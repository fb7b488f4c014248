"""The robot configs in configs/robots: every file loads; OP3 and Poppy agree with their sources."""

from __future__ import annotations

import json
import math
import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml

from robot_retarget.robot.config import RobotConfig
from robot_retarget.robot.kinematics import RobotKinematics
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.robot.servo_models import servo_model
from robot_retarget.robot.servo_units import joint_rad_range

# One folder per robot: <name>/<name>.yaml, README.md, LICENSE
ROBOT_DIRS = sorted(
    p for p in (Path(__file__).resolve().parents[2] / "configs" / "robots").iterdir()
)
CONFIG_FILES = [d / f"{d.name}.yaml" for d in ROBOT_DIRS]

# Poppy's left knee is the one joint whose mapping deliberately differs from pypot's JSON
# (its URDF limits are sign-flipped with respect to its own axis; see the YAML).
POPPY_KNEE_EXCEPTION = "l_knee_y"


@pytest.mark.parametrize("path", CONFIG_FILES, ids=[p.stem for p in CONFIG_FILES])
def test_every_config_loads(path: Path) -> None:
    config = load_robot_config(path)
    assert config.name == path.stem
    assert config.num_joints > 0
    assert np.all(config.lower < config.upper)
    for pose in (config.init_pose, config.safe_pose):
        assert pose.shape == (config.num_joints,)
        assert np.all((config.lower <= pose) & (pose <= config.upper))
    for j in config.joints:
        lo, hi = joint_rad_range(j)
        assert lo <= j.lower_rad
        assert j.upper_rad <= hi
        assert 0 < j.max_velocity_rad_s <= servo_model(j.servo_model).no_load_speed_rad_s
    kin = RobotKinematics(config)
    for b in config.bones:
        assert b.start_frame in kin.frame_names
        assert b.end_frame in kin.frame_names


def test_config_folder_is_not_empty() -> None:
    assert {p.stem for p in CONFIG_FILES} >= {"op3", "poppy_humanoid"}


@pytest.mark.parametrize("folder", ROBOT_DIRS, ids=[d.name for d in ROBOT_DIRS])
def test_every_robot_folder_has_its_config_readme_and_licence(folder: Path) -> None:
    assert (folder / f"{folder.name}.yaml").is_file()
    assert (folder / "README.md").read_text(encoding="utf-8").startswith("# ")
    assert any(p.name.startswith("LICENSE") for p in folder.iterdir())


def test_search_path_finds_user_robots_in_either_layout(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from robot_retarget.robot import loader

    text = (CONFIG_FILES[0]).read_text(encoding="utf-8")
    name = CONFIG_FILES[0].stem
    flat, folders = tmp_path / "flat", tmp_path / "folders"
    (folders / f"my_{name}").mkdir(parents=True)
    flat.mkdir()
    (flat / f"flat_{name}.yaml").write_text(
        text.replace(f"name: {name}\n", f"name: flat_{name}\n", 1)
    )
    (folders / f"my_{name}" / f"my_{name}.yaml").write_text(
        text.replace(f"name: {name}\n", f"name: my_{name}\n", 1)
    )
    monkeypatch.setenv(loader.CONFIG_DIR_ENV, os.pathsep.join([str(flat), str(folders)]))
    assert load_robot_config(f"flat_{name}").name == f"flat_{name}"
    assert load_robot_config(f"my_{name}").name == f"my_{name}"
    assert {f"flat_{name}", f"my_{name}", name} <= set(loader.available_robots())


def _urdf_revolute_joints(urdf: Path) -> dict[str, ET.Element]:
    root = ET.parse(urdf).getroot()
    return {str(j.get("name")): j for j in root.findall("joint") if j.get("type") == "revolute"}


def _vec(el: ET.Element | None, attr: str) -> tuple[float, ...]:
    assert el is not None
    return tuple(float(v) for v in str(el.get(attr)).split())


@pytest.mark.parametrize("robot", ["op3", "poppy"])
def test_kinematics_copied_exactly_from_urdf(robot: str, request: pytest.FixtureRequest) -> None:
    config: RobotConfig = request.getfixturevalue(robot)
    urdf: Path = request.getfixturevalue(f"{robot}_urdf")
    urdf_joints = _urdf_revolute_joints(urdf)
    assert set(config.joint_names) == set(urdf_joints)
    for j in config.joints:
        u = urdf_joints[j.name]
        assert j.parent_link == u.find("parent").get("link")  # type: ignore[union-attr]
        assert j.child_link == u.find("child").get("link")  # type: ignore[union-attr]
        assert j.origin_xyz == _vec(u.find("origin"), "xyz")
        assert j.origin_rpy == _vec(u.find("origin"), "rpy")
        axis = np.array(_vec(u.find("axis"), "xyz"))
        np.testing.assert_array_equal(j.axis, axis / np.linalg.norm(axis))


def test_op3_bus_ids_and_init_pose(op3: RobotConfig, robots_data: Path) -> None:
    framework = robots_data / "robotis_op3" / "framework_config"
    (bus,) = op3.buses
    assert (bus.protocol, bus.baud_rate, bus.default_port) == (2.0, 2_000_000, "/dev/ttyUSB0")
    assert op3.control_rate_hz == 125
    # IDs from OP3.robot's device table.
    ids = {}
    for line in (framework / "OP3.robot").read_text().splitlines():
        cells = [c.strip() for c in line.split("|")]
        if len(cells) >= 6 and cells[0] == "dynamixel":
            ids[cells[5]] = int(cells[2])
            assert cells[3] == "XM430-W350"
    assert {j.name: j.servo_id for j in op3.joints} == ids
    assert all(j.servo_model == "XM430-W350" for j in op3.joints)
    # Init pose = ini_pose.yaml tar_pose (degrees, keyed by servo ID).
    # ini_pose.yaml mixes tabs into its comments, which YAML forbids: drop the comments first.
    text = "\n".join(line.split("#")[0].rstrip() for line in (framework / "ini_pose.yaml").open())
    tar = yaml.safe_load(text)["tar_pose"]
    for j, q in zip(op3.joints, op3.init_pose, strict=True):
        assert q == pytest.approx(math.radians(tar[j.servo_id]), abs=1e-12), j.name
    # offset.yaml is all zero; every direction +1.
    offsets = yaml.safe_load((framework / "offset.yaml").read_text())["offset"]
    for j in op3.joints:
        assert j.zero_offset_rad == offsets[j.name] == 0
        assert j.direction == 1


def test_op3_knees_bend_one_way(op3: RobotConfig) -> None:
    l_knee = op3.joints[op3.joint_index("l_knee")]
    r_knee = op3.joints[op3.joint_index("r_knee")]
    assert l_knee.lower_rad >= 0.0
    assert l_knee.upper_rad >= math.radians(142)
    assert (r_knee.lower_rad, r_knee.upper_rad) == (-l_knee.upper_rad, -l_knee.lower_rad)
    # Mirror-symmetric limits: each r_* joint has the l_* limits, negated where its axis is.
    for j in op3.joints:
        if j.name.startswith("l_"):
            r = op3.joints[op3.joint_index("r_" + j.name[2:])]
            assert (r.lower_rad, r.upper_rad) in (
                (j.lower_rad, j.upper_rad),
                (-j.upper_rad, -j.lower_rad),
            ), j.name


def test_op3_safe_pose_is_a_stable_crouch(op3: RobotConfig) -> None:
    kin = RobotKinematics(op3)
    p = kin.frame_positions(op3.safe_pose, ["l_hip_center", "l_sole", "l_toe", "r_sole"])
    standing = kin.frame_positions(np.zeros(op3.num_joints), ["l_sole"])[0]
    assert abs(p[1, 0] - p[0, 0]) < 0.005  # sole under the hip (fore/aft)
    # Foot within 2.5° of flat: the toe sits at the sole's height.
    assert math.degrees(math.atan2(abs(p[2, 2] - p[1, 2]), p[2, 0] - p[1, 0])) < 2.5
    assert p[1, 2] - standing[2] > 0.1  # body at least 0.1 m lower than standing
    assert p[1, 2] == pytest.approx(p[3, 2])


def test_poppy_matches_pypot_json(poppy: RobotConfig, robots_data: Path) -> None:
    data = json.loads((robots_data / "poppy_humanoid" / "poppy_humanoid.json").read_text())
    motors = data["motors"]
    assert set(motors) == set(poppy.joint_names)
    for j in poppy.joints:
        m = motors[j.name]
        assert j.servo_id == m["id"]
        assert j.servo_model == {"AX-12": "AX-12A"}.get(m["type"], m["type"])
        d = 1 if m["orientation"] == "direct" else -1
        if j.name == POPPY_KNEE_EXCEPTION:
            assert (j.direction, j.zero_offset_rad) == (-d, 0.0)
            continue
        # pypot: raw = d * (angle + offset) → direction d, zero offset d * offset.
        assert j.direction == d
        assert j.zero_offset_rad == pytest.approx(math.radians(d * m["offset"]), abs=1e-12)
        lo, hi = (math.radians(v) for v in m["angle_limit"])
        # Limits are pypot's, cut to what the servo reaches where the offsets demand it.
        s_lo, s_hi = joint_rad_range(j)
        assert j.lower_rad == pytest.approx(max(lo, s_lo), abs=math.radians(0.2))
        assert j.upper_rad == pytest.approx(min(hi, s_hi), abs=math.radians(0.2))
    groups = data["motorgroups"]

    def expand(name: str) -> set[str]:
        return set().union(*(expand(n) for n in groups[name])) if name in groups else {name}

    for bus, controller in (
        ("upper_body", "upper_body_controller"),
        ("lower_body", "lower_body_controller"),
    ):
        members = set().union(
            *(expand(g) for g in data["controllers"][controller]["attached_motors"])
        )
        assert {j.name for j in poppy.joints if j.bus == bus} == members
    for b in poppy.buses:
        assert (b.protocol, b.baud_rate) == (1.0, 1_000_000)


def test_poppy_axes_face_the_front(poppy: RobotConfig) -> None:
    kin = RobotKinematics(poppy)
    zero = np.zeros(poppy.num_joints)
    p = dict(zip(kin.frame_names, kin.frame_positions(zero), strict=True))
    up = np.asarray(poppy.up_axis)
    forward = np.asarray(poppy.forward_axis)
    assert np.dot(p["head_point"] - p["l_foot"], up) > 0.6
    assert np.dot(p["l_toe"] - p["l_foot"], forward) > 0.05
    assert np.dot(p["l_thigh"] - p["r_thigh"], np.cross(up, forward)) > 0.1  # left is left
    # Both knees bend backwards within their limits (the l_knee_y correction).
    for knee, foot in (("l_knee_y", "l_foot"), ("r_knee_y", "r_foot")):
        q = zero.copy()
        q[poppy.joint_index(knee)] = poppy.joints[poppy.joint_index(knee)].lower_rad
        bent = kin.frame_positions(q, [foot])[0]
        assert np.dot(bent - p[foot], forward) < -0.1, knee

"""Load and validate robot configs (``configs/robots/<name>/<name>.yaml``) into
:class:`RobotConfig`.

Every mistake raises :class:`~robot_retarget.errors.ConfigError` naming the file, the key as a
dotted path (``joints[3].limits.lower``) and what is allowed. Nothing invalid gets past here.

Units in the YAML: metres, radians, rad/s, unless a value is tagged: ``!deg 90`` is 90° (stored
as π/2 rad), ``!rpm 46`` is 46 rpm (stored as rad/s). Tags also apply to lists: ``!deg [0, 0, 90]``.

Where configs are found: anything with a path separator or a ``.yaml``/``.yml`` suffix is a
file path. A bare name (``"op3"``) is looked up, as ``<dir>/<name>/<name>.yaml`` (one folder per
robot with its README and licence, as MuJoCo Menagerie) or ``<dir>/<name>.yaml``, in each
folder of ``$ROBOT_RETARGET_CONFIG_DIR`` (a search path: folders separated by ``os.pathsep``),
then in the robots that ship with the package: ``robot_retarget/robots`` in an installed wheel,
the repository's ``configs/robots`` in a checkout or an editable install.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import ConfigError
from robot_retarget.robot.bone_geometry import check_bone_geometry
from robot_retarget.robot.canonical_skeleton import check_required_bones
from robot_retarget.robot.config import (
    BoneConfig,
    BusConfig,
    FrameConfig,
    HardwareSettings,
    JointConfig,
    RobotConfig,
    Vec3,
)
from robot_retarget.robot.retarget_settings import RetargetSettings
from robot_retarget.robot.servo_models import (
    BAUD_RATES_TEXT,
    RPM_TO_RAD_S,
    SERVO_MODELS,
    baud_supported,
)
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS

CONFIG_DIR_ENV = "ROBOT_RETARGET_CONFIG_DIR"
_PACKAGE_DIR = Path(__file__).resolve().parents[1]  # .../robot_retarget

PROTOCOLS = (1.0, 2.0)
MAX_CONTROL_RATE_HZ = 1000.0
MAX_SERVO_ID = 252  # 253 is reserved (Protocol 2.0), 254 is broadcast
MAX_RETURN_DELAY_US = 508  # register 0–254 in 2 µs steps
_AXIS_TOL = 1e-9  # a shorter axis counts as zero
_ORTHO_TOL = 1e-6  # |up · forward| allowed after normalising
_SPEED_TOL = 1e-9  # rad/s slack when comparing with the no-load speed


_TOP_REQUIRED = (
    "name",
    "root_link",
    "up_axis",
    "forward_axis",
    "buses",
    "joints",
    "bones",
    "init_pose",
    "safe_pose",
)
_TOP_OPTIONAL = ("description", "frames", "control_rate_hz", "hardware", "retarget")
_BUS_KEYS = ("name", "protocol", "baud_rate", "default_port")
_JOINT_REQUIRED = ("name", "parent_link", "child_link", "origin", "axis", "limits", "servo")
_ORIGIN_KEYS = ("xyz", "rpy")
_LIMIT_KEYS = ("lower", "upper", "velocity")
_SERVO_REQUIRED = ("id", "model", "bus")
_SERVO_OPTIONAL = ("direction", "zero_offset")
_FRAME_REQUIRED = ("name", "parent_link", "origin")
_BONE_KEYS = ("canonical", "canonical_end", "start", "end")
_HARDWARE_KEYS = (
    "packet_timeout_ms",
    "return_delay_us",
    "profile_velocity_rad_s",
    "profile_acceleration_rad_s2",
    "torque_off_at_safe_pose",
)


# ----------------------------------------------------------------------------- finding files


def config_dirs() -> list[Path]:
    """Folders searched for a robot by name, in order (see the module docstring)."""
    dirs = [Path(d).expanduser() for d in os.environ.get(CONFIG_DIR_ENV, "").split(os.pathsep) if d]
    dirs.append(_PACKAGE_DIR / "robots")  # a wheel's package data
    dirs.append(_PACKAGE_DIR.parent / "configs" / "robots")  # a checkout
    return dirs


def _candidates(folder: Path, name: str) -> tuple[Path, Path]:
    return folder / name / f"{name}.yaml", folder / f"{name}.yaml"


def available_robots() -> list[str]:
    """Names of the robot configs that a bare name can load, sorted."""
    names: set[str] = set()
    for d in config_dirs():
        if d.is_dir():
            names.update(p.stem for p in d.glob("*.yaml"))
            names.update(p.stem for p in d.glob("*/*.yaml") if p.stem == p.parent.name)
    return sorted(names)


def resolve_config_path(name_or_path: str | os.PathLike[str]) -> Path:
    """The file a name or path refers to; ConfigError lists the known robots if none."""
    if not isinstance(name_or_path, (str, os.PathLike)):
        raise ConfigError(
            f"a robot is named by a config name or a YAML path, got {name_or_path!r}",
            allowed=", ".join(available_robots()) or "none found",
        )
    text = os.fspath(name_or_path)
    path = Path(text)
    if (
        isinstance(name_or_path, os.PathLike)
        or os.sep in text
        or "/" in text
        or (path.suffix in (".yaml", ".yml"))
    ):
        path = path.expanduser()
        if path.is_dir():  # a robot's folder, as shipped: <name>/<name>.yaml
            inside = path / f"{path.name}.yaml"
            if inside.is_file():
                return inside
            raise ConfigError(
                f"a folder, without {inside.name} in it: name the robot's YAML file",
                path=path,
            )
        if not path.is_file():
            raise ConfigError("robot config file not found", path=path)
        return path
    for d in config_dirs():
        for candidate in _candidates(d, text):
            if candidate.is_file():
                return candidate
    searched = [str(d) for d in config_dirs() if d.is_dir()]  # a folder not there is no clue
    raise ConfigError(
        f"no robot config named {text!r} (searched {', '.join(searched) or 'no folder'}); give "
        f"a robot's YAML path, or add its folder to {CONFIG_DIR_ENV}",
        allowed=", ".join(available_robots()) or "none found",
    )


def load_robot_config(name_or_path: str | os.PathLike[str]) -> RobotConfig:
    """Load, validate and return a robot config by name (``"op3"``) or path."""
    path = resolve_config_path(name_or_path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot read the file: {exc}", path=path) from exc
    return parse_robot_config(text, path=path)


def as_robot_config(robot: RobotConfig | str | os.PathLike[str]) -> RobotConfig:
    """``robot`` as it is, or loaded from a bundled robot's name or a config's path: what the
    API's classes take as their robot."""
    if isinstance(robot, RobotConfig):
        return robot
    if isinstance(robot, (str, os.PathLike)):
        return load_robot_config(robot)
    raise ConfigError(
        f"a robot is a RobotConfig (robot_retarget.load_robot), a bundled robot's name "
        f"({', '.join(available_robots())}) or a config's path, got {type(robot).__name__}"
    )


def parse_robot_config(text: str, *, path: str | os.PathLike[str] | None = None) -> RobotConfig:
    """Validate YAML text (as in a config file) into a RobotConfig; ``path`` is for messages."""
    where = None if path is None else os.fspath(path)
    try:
        data = yaml.load(text, Loader=_ConfigLoader)  # a SafeLoader subclass
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = "" if mark is None else f" at line {mark.line + 1}, column {mark.column + 1}"
        raise ConfigError(f"YAML syntax error{line}: {exc.problem or exc}", path=where) from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"YAML error: {exc}", path=where) from exc
    config = _Builder(where).robot(data)
    check_required_bones(config)
    check_bone_geometry(config)
    # The optimizer's section too, as it is read (a typo there had loaded and failed later, in
    # convert or stream; the API's load_robot took it).
    RetargetSettings.from_mapping(
        config.retarget, bone_names=tuple(b.canonical for b in config.bones), path=where
    )
    return config


# ----------------------------------------------------------------------------- YAML dialect


# libyaml's parser when PyYAML was built with it (≈ 5× faster on these files), else pure Python.
_SafeBase = yaml.CSafeLoader if yaml.__with_libyaml__ else yaml.SafeLoader


class _ConfigLoader(_SafeBase):  # type: ignore[valid-type,misc]
    """Safe loader with unit tags and duplicate-key detection."""


def _construct_mapping(loader: _ConfigLoader, node: yaml.MappingNode) -> dict[Any, Any]:
    seen: dict[Any, int] = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node)
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None,
                None,
                f"duplicate key {key!r} (first at line {seen[key] + 1})",
                key_node.start_mark,
            )
        seen[key] = key_node.start_mark.line
    return dict(loader.construct_mapping(node, deep=True))


def _scalar_number(loader: _ConfigLoader, node: yaml.ScalarNode) -> float:
    text = str(loader.construct_scalar(node))
    try:
        return float(text)
    except ValueError:
        raise yaml.constructor.ConstructorError(
            None, None, f"{node.tag} needs a number, got {text!r}", node.start_mark
        ) from None


class _Speed(float):
    """A value written with a speed's unit tag (!rpm): no angle."""


def _unit_tag(scale: float, kind: type[float] = float) -> Callable[[_ConfigLoader, yaml.Node], Any]:
    def construct(loader: _ConfigLoader, node: yaml.Node) -> Any:
        if isinstance(node, yaml.ScalarNode):
            values: list[Any] = [_scalar_number(loader, node)]
        elif isinstance(node, yaml.SequenceNode):
            values = [loader.construct_object(v) for v in node.value]
        else:
            raise yaml.constructor.ConstructorError(
                None, None, f"{node.tag} applies to a number or a list", node.start_mark
            )
        scaled = []
        for v in values:
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise yaml.constructor.ConstructorError(
                    None, None, f"{node.tag} needs numbers, got {v!r}", node.start_mark
                )
            scaled.append(kind(float(v) * scale))
        return scaled[0] if isinstance(node, yaml.ScalarNode) else scaled

    return construct


_ConfigLoader.add_constructor(
    yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG,
    _construct_mapping,
)
# YAML 1.2 reads 1e-8 as a number; PyYAML's YAML 1.1 rules need a dot (1.0e-8) and would
# hand the optimizer a string. Numbers are what anyone writing a weight means.
_ConfigLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?[0-9][0-9_]*[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)
_ConfigLoader.add_constructor("!deg", _unit_tag(math.pi / 180.0))
_ConfigLoader.add_constructor("!rpm", _unit_tag(RPM_TO_RAD_S, _Speed))


# ----------------------------------------------------------------------------- validation


class _Builder:
    """Turns the parsed YAML into dataclasses, raising ConfigError with the dotted key."""

    def __init__(self, path: str | None) -> None:
        self.path = path

    def error(self, key: str, message: str, allowed: str | None = None) -> ConfigError:
        return ConfigError(message, path=self.path, key=key or None, allowed=allowed)

    # --- primitive readers

    def mapping(
        self, value: Any, key: str, required: Sequence[str], optional: Sequence[str] = ()
    ) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.error(key, f"expected a mapping, got {_kind(value)}")
        allowed = ", ".join((*required, *optional))
        for k in value:
            if k not in required and k not in optional:
                raise self.error(_join(key, str(k)), "unknown key", allowed=allowed)
        for k in required:
            if k not in value:
                raise self.error(_join(key, k), "missing key", allowed=allowed)
        return value

    def sequence(self, value: Any, key: str, *, min_len: int = 0) -> list[Any]:
        if not isinstance(value, list):
            raise self.error(key, f"expected a list, got {_kind(value)}")
        if len(value) < min_len:
            raise self.error(key, f"needs at least {min_len} entries, got {len(value)}")
        return value

    def string(self, value: Any, key: str) -> str:
        if not isinstance(value, str) or not value.strip():
            raise self.error(key, f"expected a non-empty string, got {_kind(value)}")
        return value

    def number(self, value: Any, key: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(key, f"expected a number, got {_kind(value)}")
        out = float(value)
        if not math.isfinite(out):
            raise self.error(key, f"must be finite, got {out}")
        return out

    def angle(self, value: Any, key: str) -> float:
        """A number that is an angle (a limit, an offset, a pose): not written as a speed."""
        if isinstance(value, _Speed):
            raise self.error(key, "is an angle, written with !rpm (a speed); use !deg or radians")
        return self.number(value, key)

    def positive(self, value: Any, key: str) -> float:
        out = self.number(value, key)
        if out <= 0.0:
            raise self.error(key, f"must be > 0, got {out}", allowed="> 0")
        return out

    def integer(self, value: Any, key: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"expected an integer, got {_kind(value)}")
        return value

    def vec3(self, value: Any, key: str) -> Vec3:
        seq = self.sequence(value, key)
        if len(seq) != 3:
            raise self.error(key, f"expected 3 numbers, got {len(seq)}")
        x, y, z = (self.number(v, f"{key}[{i}]") for i, v in enumerate(seq))
        return (x, y, z)

    def unit_vec3(self, value: Any, key: str) -> Vec3:
        v = np.array(self.vec3(value, key))
        n = float(np.linalg.norm(v))
        if n < _AXIS_TOL:
            raise self.error(key, "must be a non-zero vector", allowed="any non-zero 3-vector")
        x, y, z = (float(c) for c in v / n)
        return (x, y, z)

    def unique(self, names: Sequence[str], key: str, what: str) -> None:
        seen: dict[str, int] = {}
        for i, n in enumerate(names):
            if n in seen:
                raise self.error(
                    f"{key}[{i}].name", f"duplicate {what} {n!r} (also {key}[{seen[n]}])"
                )
            seen[n] = i

    # --- sections

    def robot(self, data: Any) -> RobotConfig:
        top = self.mapping(data, "", _TOP_REQUIRED, _TOP_OPTIONAL)
        name = self.string(top["name"], "name")
        description = str(top.get("description", "") or "")
        root = self.string(top["root_link"], "root_link")
        up = self.unit_vec3(top["up_axis"], "up_axis")
        forward = self.unit_vec3(top["forward_axis"], "forward_axis")
        if abs(float(np.dot(up, forward))) > _ORTHO_TOL:
            raise self.error(
                "forward_axis", "must be perpendicular to up_axis", allowed="unit vector ⟂ up_axis"
            )
        buses = self.buses(top["buses"])
        joints = self.joints(top["joints"], {b.name: b for b in buses})
        links = self.check_tree(root, joints)
        frames = self.frames(top.get("frames", []) or [], links)
        bones = self.bones(top["bones"], links | {f.name for f in frames})
        init_pose = self.pose(top["init_pose"], "init_pose", joints)
        safe_pose = self.pose(top["safe_pose"], "safe_pose", joints)
        rate = self.positive(top.get("control_rate_hz", 100.0), "control_rate_hz")
        if rate > MAX_CONTROL_RATE_HZ:
            raise self.error(
                "control_rate_hz",
                f"{rate:g} Hz is more than a Dynamixel bus serves (a sync write and read of "
                "a robot's servos take about 1 ms)",
                allowed=f"0 < rate ≤ {MAX_CONTROL_RATE_HZ:g}",
            )
        hardware = self.hardware(top.get("hardware", {}) or {})
        self.check_profile_velocity(hardware, joints)
        retarget = self.retarget(top.get("retarget", {}) or {})
        return RobotConfig(
            name=name,
            description=description,
            source_path=self.path,
            root_link=root,
            up_axis=up,
            forward_axis=forward,
            buses=buses,
            joints=joints,
            frames=frames,
            bones=bones,
            init_pose=init_pose,
            safe_pose=safe_pose,
            control_rate_hz=rate,
            hardware=hardware,
            retarget=retarget,
        )

    def check_profile_velocity(
        self, hardware: HardwareSettings, joints: Sequence[JointConfig]
    ) -> None:
        """A profile velocity above every servo's top speed limits nothing (the servos' own
        slew limit would be off): almost surely a unit slip (deg/s, rpm)."""
        v = hardware.profile_velocity_rad_s
        fastest = max(SERVO_MODELS[j.servo_model].no_load_speed_rad_s for j in joints)
        if v is not None and v > fastest:
            raise self.error(
                "hardware.profile_velocity_rad_s",
                f"{v:g} rad/s is above every servo's no-load speed (the fastest: "
                f"{fastest:.2f} rad/s), so it would limit nothing; in rad/s (a unit tag such as "
                "!rpm converts)",
                allowed=f"0 < v ≤ {fastest:.2f}",
            )

    def buses(self, value: Any) -> tuple[BusConfig, ...]:
        out = []
        for i, item in enumerate(self.sequence(value, "buses", min_len=1)):
            key = f"buses[{i}]"
            m = self.mapping(item, key, _BUS_KEYS)
            protocol = self.number(m["protocol"], f"{key}.protocol")
            if protocol not in PROTOCOLS:
                raise self.error(f"{key}.protocol", f"unknown protocol {protocol}", "1.0, 2.0")
            baud = self.integer(m["baud_rate"], f"{key}.baud_rate")
            if not baud_supported(protocol, baud):
                raise self.error(
                    f"{key}.baud_rate",
                    f"{baud} bps is not a rate Protocol {protocol} servos can be set to",
                    allowed=BAUD_RATES_TEXT[protocol],
                )
            out.append(
                BusConfig(
                    name=self.string(m["name"], f"{key}.name"),
                    protocol=protocol,
                    baud_rate=baud,
                    default_port=self.string(m["default_port"], f"{key}.default_port"),
                )
            )
        self.unique([b.name for b in out], "buses", "bus name")
        return tuple(out)

    def joints(self, value: Any, buses: Mapping[str, BusConfig]) -> tuple[JointConfig, ...]:
        out = [
            self.named_joint(item, f"joints[{i}]", buses)
            for i, item in enumerate(self.sequence(value, "joints", min_len=1))
        ]
        self.unique([j.name for j in out], "joints", "joint name")
        ids: dict[tuple[str, int], int] = {}
        for i, j in enumerate(out):
            slot = (j.bus, j.servo_id)
            if slot in ids:
                raise self.error(
                    f"joints[{i}].servo.id",
                    f"servo id {j.servo_id} is already used on bus {j.bus!r} by "
                    f"joints[{ids[slot]}] ({out[ids[slot]].name})",
                    allowed="ids unique per bus",
                )
            ids[slot] = i
        return tuple(out)

    def named_joint(self, item: Any, key: str, buses: Mapping[str, BusConfig]) -> JointConfig:
        """:meth:`joint`, its errors also naming the joint (a long file's list index is hard
        to count to)."""
        try:
            return self.joint(item, key, buses)
        except ConfigError as e:
            name = item.get("name") if isinstance(item, dict) else None
            if not isinstance(name, str) or e.key is None or not e.key.startswith(key + "."):
                raise
            raise ConfigError(
                f"{e.message} (joint {name!r})", path=e.path, key=e.key, allowed=e.allowed
            ) from None

    def joint(self, item: Any, key: str, buses: Mapping[str, BusConfig]) -> JointConfig:
        m = self.mapping(item, key, _JOINT_REQUIRED)
        name = self.string(m["name"], f"{key}.name")
        origin = self.mapping(m["origin"], f"{key}.origin", _ORIGIN_KEYS)
        limits = self.mapping(m["limits"], f"{key}.limits", _LIMIT_KEYS)
        servo = self.mapping(m["servo"], f"{key}.servo", _SERVO_REQUIRED, _SERVO_OPTIONAL)

        model_name = self.string(servo["model"], f"{key}.servo.model")
        if model_name not in SERVO_MODELS:
            raise self.error(
                f"{key}.servo.model",
                f"unknown servo model {model_name!r}",
                allowed=", ".join(sorted(SERVO_MODELS)),
            )
        model = SERVO_MODELS[model_name]
        bus_name = self.string(servo["bus"], f"{key}.servo.bus")
        if bus_name not in buses:
            raise self.error(
                f"{key}.servo.bus", f"no bus named {bus_name!r}", allowed=", ".join(buses)
            )
        if buses[bus_name].protocol not in model.protocols:
            raise self.error(
                f"{key}.servo.model",
                f"this tool drives {model_name} over Protocol "
                f"{' or '.join(str(p) for p in model.protocols)} only (its control table for "
                f"that firmware), and bus {bus_name!r} is Protocol {buses[bus_name].protocol}",
                allowed=f"protocol {', '.join(str(p) for p in model.protocols)} for {model_name}",
            )
        servo_id = self.integer(servo["id"], f"{key}.servo.id")
        if not 0 <= servo_id <= MAX_SERVO_ID:
            raise self.error(
                f"{key}.servo.id", f"servo id {servo_id} out of range", f"0…{MAX_SERVO_ID}"
            )
        direction = self.integer(servo.get("direction", 1), f"{key}.servo.direction")
        if direction not in (-1, 1):
            raise self.error(f"{key}.servo.direction", f"got {direction}", allowed="-1, 1")
        zero_offset = self.angle(servo.get("zero_offset", 0.0), f"{key}.servo.zero_offset")
        if abs(zero_offset) > math.pi:
            raise self.error(
                f"{key}.servo.zero_offset",
                f"{zero_offset:g} rad is more than half a turn: radians, not degrees or ticks "
                "(!deg converts degrees)",
                allowed="−π … π rad",
            )

        lower = self.angle(limits["lower"], f"{key}.limits.lower")
        upper = self.angle(limits["upper"], f"{key}.limits.upper")
        if lower >= upper:
            raise self.error(
                f"{key}.limits.lower",
                f"lower ({lower:.6f} rad) must be below upper ({upper:.6f} rad)",
                allowed="lower < upper",
            )
        # The servo reaches servo_rad = direction * q + zero_offset only within its tick range.
        s_lo = (model.min_tick - model.zero_tick) * model.rad_per_tick
        s_hi = (model.max_tick - model.zero_tick) * model.rad_per_tick
        q_a = (s_lo - zero_offset) * direction
        q_b = (s_hi - zero_offset) * direction
        q_lo, q_hi = min(q_a, q_b), max(q_a, q_b)
        for bound, value in (("lower", lower), ("upper", upper)):
            if not q_lo <= value <= q_hi:
                raise self.error(
                    f"{key}.limits.{bound}",
                    f"{value:.6f} rad ({math.degrees(value):.2f}°) is outside what the "
                    f"{model_name} reaches with direction {direction:+d} and zero offset "
                    f"{zero_offset:.6f} rad",
                    allowed=f"{q_lo:.6f} … {q_hi:.6f} rad "
                    f"({math.degrees(q_lo):.2f}° … {math.degrees(q_hi):.2f}°)",
                )
        velocity = self.positive(limits["velocity"], f"{key}.limits.velocity")
        if velocity > model.no_load_speed_rad_s + _SPEED_TOL:
            raise self.error(
                f"{key}.limits.velocity",
                f"{velocity:.4f} rad/s exceeds the {model_name}'s no-load speed",
                allowed=f"0 < velocity ≤ {model.no_load_speed_rad_s:.4f} rad/s",
            )
        return JointConfig(
            name=name,
            parent_link=self.string(m["parent_link"], f"{key}.parent_link"),
            child_link=self.string(m["child_link"], f"{key}.child_link"),
            origin_xyz=self.vec3(origin["xyz"], f"{key}.origin.xyz"),
            origin_rpy=self.vec3(origin["rpy"], f"{key}.origin.rpy"),
            axis=self.unit_vec3(m["axis"], f"{key}.axis"),
            lower_rad=lower,
            upper_rad=upper,
            max_velocity_rad_s=velocity,
            servo_id=servo_id,
            servo_model=model_name,
            bus=bus_name,
            direction=direction,
            zero_offset_rad=zero_offset,
        )

    def check_tree(self, root: str, joints: Sequence[JointConfig]) -> set[str]:
        """The link names; the joints must form one tree hanging from ``root``."""
        child_of: dict[str, int] = {}
        for i, j in enumerate(joints):
            if j.child_link == root:
                raise self.error(
                    f"joints[{i}].child_link",
                    f"the root link {root!r} cannot be a joint's child",
                    allowed="any link except the root",
                )
            if j.child_link in child_of:
                raise self.error(
                    f"joints[{i}].child_link",
                    f"link {j.child_link!r} is already the child of "
                    f"joints[{child_of[j.child_link]}]; a link has one parent joint",
                )
            child_of[j.child_link] = i
        links = {root, *child_of}
        if root not in {j.parent_link for j in joints}:
            raise self.error(
                "root_link",
                f"no joint hangs from {root!r}: the root link is the parent_link of the joints "
                "nearest the trunk",
                allowed=", ".join(sorted({j.parent_link for j in joints} - set(child_of))),
            )
        for i, j in enumerate(joints):
            if j.parent_link not in links:
                raise self.error(
                    f"joints[{i}].parent_link",
                    f"unknown link {j.parent_link!r} (every link but the root must be some "
                    "joint's child_link)",
                    allowed=", ".join(sorted(links)),
                )
        # Every link must reach the root through parents; otherwise there is a cycle.
        for i, j in enumerate(joints):
            seen = {j.child_link}
            link = j.parent_link
            while link != root:
                if link in seen:
                    raise self.error(
                        f"joints[{i}].parent_link",
                        f"the joints form a cycle through link {link!r}; they must form a tree "
                        f"rooted at {root!r}",
                    )
                seen.add(link)
                link = joints[child_of[link]].parent_link
        return links

    def frames(self, value: Any, links: set[str]) -> tuple[FrameConfig, ...]:
        out = []
        for i, item in enumerate(self.sequence(value, "frames")):
            key = f"frames[{i}]"
            m = self.mapping(item, key, _FRAME_REQUIRED)
            name = self.string(m["name"], f"{key}.name")
            if name in links:
                raise self.error(f"{key}.name", f"{name!r} is already a link name")
            parent = self.string(m["parent_link"], f"{key}.parent_link")
            if parent not in links:
                raise self.error(
                    f"{key}.parent_link", f"unknown link {parent!r}", ", ".join(sorted(links))
                )
            origin = self.mapping(m["origin"], f"{key}.origin", ("xyz",), ("rpy",))
            out.append(
                FrameConfig(
                    name=name,
                    parent_link=parent,
                    origin_xyz=self.vec3(origin["xyz"], f"{key}.origin.xyz"),
                    origin_rpy=self.vec3(origin.get("rpy", [0.0, 0.0, 0.0]), f"{key}.origin.rpy"),
                )
            )
        self.unique([f.name for f in out], "frames", "frame name")
        return tuple(out)

    def bones(self, value: Any, frames: set[str]) -> tuple[BoneConfig, ...]:
        out = []
        ends: dict[str, int] = {}
        for i, item in enumerate(self.sequence(value, "bones", min_len=1)):
            key = f"bones[{i}]"
            m = self.mapping(item, key, _BONE_KEYS)
            start = self.canonical_joint(m["canonical"], f"{key}.canonical")
            end = self.canonical_joint(m["canonical_end"], f"{key}.canonical_end")
            if not _is_ancestor(CANONICAL_JOINTS.index(start), CANONICAL_JOINTS.index(end)):
                raise self.error(
                    f"{key}.canonical_end",
                    f"{end} does not lie below {start} in the canonical skeleton",
                    allowed=f"a descendant of {start}",
                )
            if end in ends:
                raise self.error(
                    f"{key}.canonical_end", f"bone ending at {end} is also bones[{ends[end]}]"
                )
            ends[end] = i
            frame_names = []
            for k in ("start", "end"):
                f = self.string(m[k], f"{key}.{k}")
                if f not in frames:
                    raise self.error(
                        f"{key}.{k}", f"unknown frame {f!r}", allowed=", ".join(sorted(frames))
                    )
                frame_names.append(f)
            if frame_names[0] == frame_names[1]:
                raise self.error(f"{key}.end", "a bone needs two different frames")
            out.append(BoneConfig(start, end, frame_names[0], frame_names[1]))
        return tuple(out)

    def canonical_joint(self, value: Any, key: str) -> str:
        name = self.string(value, key)
        if name not in CANONICAL_JOINTS:
            raise self.error(key, f"unknown canonical joint {name!r}", ", ".join(CANONICAL_JOINTS))
        return name

    def pose(self, value: Any, key: str, joints: Sequence[JointConfig]) -> FloatArray:
        names = [j.name for j in joints]
        m = self.mapping(value, key, names)
        out = np.empty(len(joints))
        for i, j in enumerate(joints):
            q = self.angle(m[j.name], f"{key}.{j.name}")
            if not j.lower_rad <= q <= j.upper_rad:
                raise self.error(
                    f"{key}.{j.name}",
                    f"{q:.6f} rad ({math.degrees(q):.2f}°) is outside the joint limits",
                    allowed=f"{j.lower_rad:.6f} … {j.upper_rad:.6f} rad",
                )
            out[i] = q
        out.setflags(write=False)
        return out

    def hardware(self, value: Any) -> HardwareSettings:
        m = self.mapping(value, "hardware", (), _HARDWARE_KEYS)
        defaults = HardwareSettings()
        timeout = self.positive(
            m.get("packet_timeout_ms", defaults.packet_timeout_ms), "hardware.packet_timeout_ms"
        )
        delay = self.integer(
            m.get("return_delay_us", defaults.return_delay_us), "hardware.return_delay_us"
        )
        if not 0 <= delay <= MAX_RETURN_DELAY_US or delay % 2:
            raise self.error(
                "hardware.return_delay_us",
                f"got {delay}",
                allowed=f"an even number 0…{MAX_RETURN_DELAY_US}",
            )
        optional: list[float | None] = []
        for k in ("profile_velocity_rad_s", "profile_acceleration_rad_s2"):
            raw = m.get(k)
            optional.append(None if raw is None else self.positive(raw, f"hardware.{k}"))
        torque_off = m.get("torque_off_at_safe_pose", defaults.torque_off_at_safe_pose)
        if not isinstance(torque_off, bool):
            raise self.error(
                "hardware.torque_off_at_safe_pose", f"got {_kind(torque_off)}", "true, false"
            )
        return HardwareSettings(
            packet_timeout_ms=timeout,
            return_delay_us=delay,
            profile_velocity_rad_s=optional[0],
            profile_acceleration_rad_s2=optional[1],
            torque_off_at_safe_pose=torque_off,
        )

    def retarget(self, value: Any) -> dict[str, float]:
        if not isinstance(value, dict):
            raise self.error("retarget", f"expected a mapping, got {_kind(value)}")
        out = {}
        for k, v in value.items():
            key = self.string(k, "retarget")
            if isinstance(v, bool):  # every option is a number; level_feet reads like a switch
                raise self.error(
                    f"retarget.{key}", f"expected a number, got {v!r}: write {int(v)} instead"
                )
            out[key] = self.number(v, f"retarget.{key}")
        return out


# ----------------------------------------------------------------------------- helpers


def _join(prefix: str, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key


def _kind(value: Any) -> str:
    if value is None:
        return "nothing (null)"
    return f"{type(value).__name__} {value!r}"[:80]


def _is_ancestor(a: int, b: int) -> bool:
    """Whether canonical joint ``a`` is a proper ancestor of ``b``."""
    p = CANONICAL_PARENTS[b]
    while p >= 0:
        if p == a:
            return True
        p = CANONICAL_PARENTS[p]
    return False

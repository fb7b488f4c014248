"""Robot configuration: frozen dataclasses, the validated form of a robot YAML
(``configs/robots/<name>/<name>.yaml``).

The loader (``robot_retarget.robot.loader.load_robot_config``) builds these and validates
everything; stages downstream never see an invalid config. Joint order in ``joints`` is the
command order everywhere (JointCommand.q, trajectories, the optimizer's variables).

Sign conventions: a joint angle ``q`` is in the robot description's own convention (the URDF
joint axis, right-hand rule). The servo sees ``servo_rad = direction * q + zero_offset_rad``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from robot_retarget.array_types import FloatArray

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class BusConfig:
    """One serial bus (a U2D2 / USB2AX / OpenCR port)."""

    name: str
    protocol: float  # 1.0 or 2.0
    baud_rate: int
    default_port: str


@dataclass(frozen=True)
class JointConfig:
    """One revolute joint driven by one servo."""

    name: str
    parent_link: str
    child_link: str
    origin_xyz: Vec3  # joint frame in the parent link frame (m)
    origin_rpy: Vec3  # URDF fixed-axis roll, pitch, yaw (rad)
    axis: Vec3  # unit rotation axis in the joint frame
    lower_rad: float
    upper_rad: float
    max_velocity_rad_s: float
    servo_id: int
    servo_model: str  # key of robot_retarget.robot.servo_models.SERVO_MODELS
    bus: str  # name of a BusConfig
    direction: int = 1  # +1 or −1
    zero_offset_rad: float = 0.0


@dataclass(frozen=True)
class FrameConfig:
    """A fixed frame (no servo) rigidly attached to a link, e.g. a hand point or a foot sole."""

    name: str
    parent_link: str
    origin_xyz: Vec3
    origin_rpy: Vec3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class BoneConfig:
    """A canonical human bone realised by two robot frames (link origins or fixed frames).

    ``canonical`` names the canonical joint where the bone starts and ``canonical_end`` the one
    where it ends, e.g. the upper arm is LeftArm → LeftForeArm.
    """

    canonical: str
    canonical_end: str
    start_frame: str
    end_frame: str


@dataclass(frozen=True)
class HardwareSettings:
    """Servo-side settings applied at connect time."""

    packet_timeout_ms: float = 4.0
    return_delay_us: int = 0
    profile_velocity_rad_s: float | None = None  # None: servo default (no profile limit)
    profile_acceleration_rad_s2: float | None = None
    torque_off_at_safe_pose: bool = False


@dataclass(frozen=True)
class RobotConfig:
    """A whole robot, validated."""

    name: str
    description: str
    source_path: str | None
    root_link: str
    up_axis: Vec3  # in the root link frame: the world's up when the robot stands
    forward_axis: Vec3  # in the root link frame: where the robot faces
    buses: tuple[BusConfig, ...]
    joints: tuple[JointConfig, ...]
    frames: tuple[FrameConfig, ...]
    bones: tuple[BoneConfig, ...]
    init_pose: FloatArray = field(repr=False)  # (J,) rad, standing pose
    safe_pose: FloatArray = field(repr=False)  # (J,) rad, pose to rest in on stop / watchdog
    control_rate_hz: float = 100.0
    hardware: HardwareSettings = field(default_factory=HardwareSettings)
    # Optimizer weights and options (validated by the optimizer, which owns their meaning).
    retarget: Mapping[str, float] = field(default_factory=dict)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    @property
    def num_joints(self) -> int:
        return len(self.joints)

    @property
    def lower(self) -> FloatArray:
        return np.array([j.lower_rad for j in self.joints])

    @property
    def upper(self) -> FloatArray:
        return np.array([j.upper_rad for j in self.joints])

    @property
    def max_velocity(self) -> FloatArray:
        return np.array([j.max_velocity_rad_s for j in self.joints])

    def joint_index(self, name: str) -> int:
        for i, j in enumerate(self.joints):
            if j.name == name:
                return i
        raise KeyError(f"robot {self.name} has no joint {name!r}; joints: {self.joint_names}")

    def bus(self, name: str) -> BusConfig:
        for b in self.buses:
            if b.name == name:
                return b
        raise KeyError(f"robot {self.name} has no bus {name!r}")

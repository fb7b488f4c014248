"""HumanMotion: a clip on the canonical 22-joint human skeleton, the input of every model.

Local rotations are unit quaternions (w, x, y, z), sign-continuous over time; lengths are in
metres; Y is up. ``load_motion`` reads a motion file and maps it onto this form.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from robot_retarget.array_types import FloatArray
from robot_retarget.errors import InvalidMotionError, MotionFormatError
from robot_retarget.geometry import euler
from robot_retarget.geometry import quaternion as quat
from robot_retarget.motion.bvh import (
    DEFAULT_JOINT_CHANNELS,
    DEFAULT_ROOT_CHANNELS,
    POSITION_CHANNELS,
    ROTATION_CHANNELS,
    BvhClip,
)
from robot_retarget.motion.units import unit_scale_m
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS, CANONICAL_PARENTS, Joint
from robot_retarget.skeleton.skeleton import Skeleton, forward_kinematics

CANONICAL_FAMILY = "canonical"
_UNIT_TOL = 1e-6


def standing_height(
    hips: FloatArray,
    head_top: FloatArray,
    up_legs: Sequence[FloatArray],
    knees: Sequence[FloatArray],
    ankles: Sequence[FloatArray],
    soles: Sequence[FloatArray],
) -> float:
    """Standing height (Y up, any unit) with straightened legs, from rest-pose points.

    Head top above the hips, plus per leg: hip-joint drop below the hips, thigh and shin lengths
    and the ankle's height above the sole, averaged over the legs. Straightening makes A-poses
    and splayed rest legs (the CMU conversion's) measure like a T-pose.
    """
    legs = [
        (hips[1] - h[1]) + np.linalg.norm(k - h) + np.linalg.norm(a - k) + max(0.0, a[1] - s[1])
        for h, k, a, s in zip(up_legs, knees, ankles, soles, strict=True)
    ]
    return float(head_top[1] - hips[1] + np.mean(legs))


def skeleton_height(skeleton: Skeleton) -> float:
    """Standing height (m) of a canonical skeleton: :func:`standing_height` of its rest pose."""
    rest = skeleton.rest_positions()
    sides = ("Left", "Right")
    return standing_height(
        rest[Joint.Hips],
        rest[Joint.Head],
        [rest[Joint[s + "UpLeg"]] for s in sides],
        [rest[Joint[s + "Leg"]] for s in sides],
        [rest[Joint[s + "Foot"]] for s in sides],
        [rest[Joint[s + "ToeBase"]] for s in sides],
    )


@dataclass(frozen=True, eq=False)
class HumanMotion:
    """A motion on the canonical skeleton (robot_retarget.skeleton.canonical).

    ``skeleton`` offsets are metres; ``local_quats`` (T, 22, 4) are local rotations;
    ``root_pos`` (T, 3) is the Hips position in metres; Y is up. The remaining fields describe
    where the motion came from: ``source_joints`` names the source joint of each canonical
    joint (None where synthesised), ``tpose_frames_dropped`` how many synthetic leading
    T-pose frames were removed.
    """

    skeleton: Skeleton
    local_quats: FloatArray = field(repr=False)
    root_pos: FloatArray = field(repr=False)
    fps: float
    source_path: str | None = None
    name_family: str = CANONICAL_FAMILY
    unit: str = "m"
    height_m: float = float("nan")
    tpose_frames_dropped: int = 0
    up_axis: str = "y"
    source_joints: tuple[str | None, ...] = ()

    def __post_init__(self) -> None:
        if self.skeleton.names != CANONICAL_JOINTS or self.skeleton.parents != CANONICAL_PARENTS:
            raise InvalidMotionError(
                "HumanMotion needs the canonical 22-joint skeleton (CANONICAL_JOINTS)"
            )
        q = np.array(self.local_quats, dtype=np.float64)
        root = np.array(self.root_pos, dtype=np.float64)
        if q.ndim != 3 or q.shape[1:] != (len(CANONICAL_JOINTS), 4) or q.shape[0] == 0:
            raise InvalidMotionError(f"local_quats must have shape (T>0, 22, 4), got {q.shape}")
        if root.shape != (q.shape[0], 3):
            raise InvalidMotionError(
                f"root_pos must have shape ({q.shape[0]}, 3), got {root.shape}"
            )
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(root))):
            raise InvalidMotionError("local_quats and root_pos must be finite")
        norms = np.linalg.norm(q, axis=-1)
        if np.any(np.abs(norms - 1.0) > _UNIT_TOL):
            worst = float(norms.flat[np.argmax(np.abs(norms - 1.0))])
            raise InvalidMotionError(
                f"local_quats must be unit quaternions (worst norm {worst:.6g})"
            )
        if not (math.isfinite(self.fps) and self.fps > 0.0):
            raise InvalidMotionError(f"fps must be positive, got {self.fps}")
        if self.source_joints and len(self.source_joints) != len(CANONICAL_JOINTS):
            raise InvalidMotionError("source_joints needs one entry per canonical joint")
        q = quat.make_continuous(q / norms[..., None], axis=0)
        q.setflags(write=False)
        root.setflags(write=False)
        object.__setattr__(self, "local_quats", q)
        object.__setattr__(self, "root_pos", root)
        object.__setattr__(self, "fps", float(self.fps))
        if math.isnan(self.height_m):
            object.__setattr__(self, "height_m", skeleton_height(self.skeleton))

    # --- sizes ---------------------------------------------------------------------------

    @property
    def num_frames(self) -> int:
        return int(self.local_quats.shape[0])

    @property
    def duration_s(self) -> float:
        """Number of frames / fps (each frame lasts 1 / fps)."""
        return self.num_frames / self.fps

    @property
    def dropped_tpose(self) -> bool:
        return self.tpose_frames_dropped > 0

    @property
    def synthesized_joints(self) -> tuple[str, ...]:
        """Canonical joints with no source joint of their own (empty if unknown)."""
        if not self.source_joints:
            return ()
        return tuple(
            c for c, s in zip(CANONICAL_JOINTS, self.source_joints, strict=True) if s is None
        )

    # --- kinematics ----------------------------------------------------------------------

    def positions(self) -> FloatArray:
        """Global joint positions (T, 22, 3) in metres."""
        return forward_kinematics(self.skeleton, self.local_quats, self.root_pos)[0]

    def global_quats(self) -> FloatArray:
        """Global joint rotations (T, 22, 4)."""
        return forward_kinematics(self.skeleton, self.local_quats, self.root_pos)[1]

    # --- editing -------------------------------------------------------------------------

    def frames(self, start: int = 0, stop: int | None = None) -> HumanMotion:
        """The motion restricted to frames ``start:stop``."""
        q = self.local_quats[start:stop]
        if q.shape[0] == 0:
            raise InvalidMotionError(
                f"frames({start}, {stop}) selects no frame of {self.num_frames}"
            )
        return dataclasses.replace(self, local_quats=q, root_pos=self.root_pos[start:stop])

    def resample(self, fps: float) -> HumanMotion:
        """Resample to ``fps`` over the same time span: slerp rotations, lerp the root."""
        if not (math.isfinite(fps) and fps > 0.0):
            raise InvalidMotionError(f"fps must be positive, got {fps}")
        span_s = (self.num_frames - 1) / self.fps
        count = math.floor(span_s * fps + 1e-9) + 1
        x = np.arange(count) * (self.fps / fps)
        i0 = np.clip(np.floor(x).astype(np.int64), 0, self.num_frames - 1)
        i1 = np.minimum(i0 + 1, self.num_frames - 1)
        w = x - i0
        q = quat.slerp(self.local_quats[i0], self.local_quats[i1], w[:, None])
        root = self.root_pos[i0] + w[:, None] * (self.root_pos[i1] - self.root_pos[i0])
        return dataclasses.replace(self, local_quats=q, root_pos=root, fps=float(fps))

    # --- export --------------------------------------------------------------------------

    def to_bvh_clip(
        self,
        *,
        root_channels: Sequence[str] = DEFAULT_ROOT_CHANNELS,
        joint_channels: Sequence[str] = DEFAULT_JOINT_CHANNELS,
        unit: str = "m",
    ) -> BvhClip:
        """This motion as a BVH clip on the canonical joints, in ``unit`` lengths."""
        scale = unit_scale_m(unit)
        offsets = self.skeleton.offsets / scale
        root_trans = self.root_pos / scale
        columns: list[FloatArray] = []
        channels: list[tuple[str, ...]] = []
        for j in range(len(CANONICAL_JOINTS)):
            chans = tuple(root_channels if j == 0 else joint_channels)
            channels.append(chans)
            columns.append(self._channel_values(j, chans, offsets, root_trans))
        leaves = [j for j in range(len(CANONICAL_JOINTS)) if j not in CANONICAL_PARENTS]
        return BvhClip(
            CANONICAL_JOINTS,
            CANONICAL_PARENTS,
            offsets,
            tuple(channels),
            tuple(leaves),
            np.zeros((len(leaves), 3)),
            1.0 / self.fps,
            np.concatenate(columns, axis=1),
            self.source_path,
        )

    def _channel_values(
        self, j: int, chans: tuple[str, ...], offsets: FloatArray, root_trans: FloatArray
    ) -> FloatArray:
        unknown = [c for c in chans if c not in POSITION_CHANNELS + ROTATION_CHANNELS]
        rot = [c[0] for c in chans if c in ROTATION_CHANNELS]
        if unknown or len(rot) != 3 or len(set(rot)) != 3:
            raise MotionFormatError(
                f"channels {chans} for joint {CANONICAL_JOINTS[j]} must name three different "
                "rotation axes (and optionally positions) spelled like BVH, e.g. "
                "Zrotation Yrotation Xrotation"
            )
        angles = np.degrees(euler.to_euler(self.local_quats[:, j], "".join(rot)))
        trans = root_trans if j == 0 else np.broadcast_to(offsets[j], root_trans.shape)
        out = np.empty((self.num_frames, len(chans)))
        r = 0
        for k, c in enumerate(chans):
            if c in POSITION_CHANNELS:
                out[:, k] = trans[:, "XYZ".index(c[0])]
            else:
                out[:, k] = angles[:, r]
                r += 1
        return out


def load_motion(
    path: str | Path,
    *,
    unit: str | None = None,
    drop_tpose: bool | Literal["auto"] = "auto",
    max_frames: int | None = None,
    up_axis: str | None = None,
    family: str | None = None,
) -> HumanMotion:
    """Read a motion file (BVH) onto the canonical skeleton.

    ``unit`` overrides the detected length unit (see robot_retarget.motion.units); ``drop_tpose``
    "auto" drops detected synthetic leading T-pose frames, False keeps every frame, True drops
    them and at least the first frame; ``max_frames`` keeps only the first frames (after the
    drop); ``up_axis`` ("y", "z", "-z", …) overrides the detected up axis; ``family`` forces a
    naming family (robot_retarget.motion.joint_map.FAMILIES).
    """
    return load_bvh_motion(
        path,
        unit=unit,
        drop_tpose=drop_tpose,
        max_frames=max_frames,
        up_axis=up_axis,
        family=family,
    )[1]


def load_bvh_motion(
    path: str | Path,
    *,
    unit: str | None = None,
    drop_tpose: bool | Literal["auto"] = "auto",
    max_frames: int | None = None,
    up_axis: str | None = None,
    family: str | None = None,
) -> tuple[BvhClip, HumanMotion]:
    """:func:`load_motion`, and the file as it was read: for readers of the file's own
    skeleton (robot_retarget.motion.native_pose) without parsing it twice."""
    from robot_retarget.motion.canonicalize import canonicalize
    from robot_retarget.motion.tpose import MAX_SYNTHETIC_FRAMES

    p = Path(path)
    if max_frames is not None and max_frames < 1:
        raise ValueError(f"max_frames must be at least 1, got {max_frames}")
    if p.suffix.lower() != ".bvh":
        raise MotionFormatError(
            f"not a motion clip ({p.suffix or 'no suffix'}): motion is read from .bvh files"
            + (
                " (an .npz, .csv or robot .json is a trajectory: `view` shows it, `inspect` "
                "describes it)"
                if p.suffix.lower() in (".npz", ".csv")
                else ""
            ),
            path=p,
        )
    from robot_retarget.motion.bvh import read_bvh

    extra = MAX_SYNTHETIC_FRAMES + 12 if drop_tpose is not False else 0
    clip = read_bvh(p, max_frames=None if max_frames is None else max_frames + extra)
    motion = canonicalize(clip, unit=unit, drop_tpose=drop_tpose, up_axis=up_axis, family=family)
    if max_frames is not None and motion.num_frames > max_frames:
        motion = motion.frames(0, max_frames)
    return clip, motion

"""A sender that got the wire conventions wrong is told so (a warning; nothing dropped)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robot_retarget.motion.human_motion import HumanMotion, load_motion
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.sources import wire
from robot_retarget.sources.udp import UdpSource
from robot_retarget.sources.wire_sanity import WireSanity


def _warnings(
    motion: HumanMotion, positions: np.ndarray | None = None, quats: np.ndarray | None = None
) -> list[str]:
    """The warnings of one stream of ``positions`` or ``quats`` at the motion's rate."""
    sanity = WireSanity()
    out = []
    for k in range(motion.num_frames):
        t = k / motion.fps
        if positions is not None:
            w = sanity.positions(positions[k], t)
        else:
            assert quats is not None
            w = sanity.rotations(quats[k], t)
        if w is not None:
            out.append(w)
    return out


@pytest.fixture(scope="module")
def bending(shared_data_dir: Path) -> HumanMotion:
    """05_06: the performer bends over, the head below 60° above the hips for 1.05 s."""
    return load_motion(shared_data_dir / "mocap" / "05" / "05_06.bvh")


def test_real_motion_raises_no_warning(bending: HumanMotion) -> None:
    for motion in (bending, demo_motion(fps=30.0)):
        assert _warnings(motion, motion.positions()) == []
        assert _warnings(motion, quats=motion.local_quats) == []


def test_z_up_positions_and_a_reversed_joint_order_are_told(bending: HumanMotion) -> None:
    p = bending.positions()
    z_up = np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)  # a Z-up sender's frames
    warned = _warnings(bending, z_up)
    assert len(warned) == 1  # once per stream
    assert "Y up" in warned[0]
    assert "joint order" in warned[0]
    assert len(_warnings(bending, p[:, ::-1])) == 1


def test_quaternions_sent_scalar_last_are_told(bending: HumanMotion) -> None:
    xyzw = bending.local_quats[..., [1, 2, 3, 0]]
    warned = _warnings(bending, quats=xyzw)
    assert len(warned) == 1
    assert "x-y-z-w" in warned[0]


def test_the_udp_source_warns_live_and_drops_nothing() -> None:
    motion = demo_motion(fps=30.0)
    src = UdpSource("127.0.0.1", 0, skeleton=motion.skeleton, nominal_fps=30.0)
    xyzw = motion.local_quats[..., [1, 2, 3, 0]]
    for k in range(45):
        packet = wire.encode_binary(wire.KIND_ROTATIONS, k, k / 30, xyzw[k], motion.root_pos[k])
        assert src.handle_packet(packet, 0.0) is not None
    assert src.stats.dropped_total == 0
    assert any("x-y-z-w" in w for w in src.stats.warnings)

"""SafetyLayer: nothing outside the limits or the step bound ever reaches the backend."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.errors import HardwareError
from robot_retarget.hardware.safety import SafetyLayer, UnsafeCommandError
from robot_retarget.hardware.types import JointCommand
from robot_retarget.robot.config import RobotConfig
from robot_retarget.sim.backend import SimBackend


def _layer(config: RobotConfig) -> tuple[SafetyLayer, SimBackend]:
    inner = SimBackend(config, realtime=False)
    safe = SafetyLayer(config, inner)
    safe.connect()
    return safe, inner


@settings(max_examples=60)
@given(st.data())
def test_no_command_ever_leaves_the_limits(op3: RobotConfig, data: st.DataObject) -> None:
    safe, inner = _layer(op3)
    n = op3.num_joints
    period = 1.0 / op3.control_rate_hz
    prev = op3.init_pose.copy()
    t = 0.0
    for _ in range(data.draw(st.integers(1, 15))):
        q = data.draw(arrays(np.float64, n, elements=st.floats(-50, 50)))
        step = data.draw(st.sampled_from([period, period / 3, 5 * period, 0.0, -1.0]))
        if step <= 0.0 and inner.sent:  # a time that does not advance: refused, nothing sent
            before = len(inner.sent)
            with pytest.raises(UnsafeCommandError, match="does not come after"):
                safe.send(JointCommand(q, t + step))
            assert len(inner.sent) == before
            continue
        t += max(step, 0.0)
        sent = safe.send(JointCommand(q, t))
        assert np.all(sent.q >= op3.lower - 1e-12)
        assert np.all(sent.q <= op3.upper + 1e-12)
        assert np.all(np.abs(sent.q - prev) <= op3.max_velocity * period + 1e-9)
        np.testing.assert_array_equal(inner.sent[-1].q, sent.q)
        prev = sent.q


@settings(max_examples=60)
@given(st.data())
def test_each_command_is_the_nearest_safe_one_and_every_clip_is_counted(
    op3: RobotConfig, data: st.DataObject
) -> None:
    """The layer's one clamp to (limits ∩ step box) against its definition: the limit clamp,
    then the step clamp around the previous command; and its statistics against a count."""
    safe, _ = _layer(op3)
    n = op3.num_joints
    period = 1.0 / op3.control_rate_hz
    prev, prev_t = np.clip(op3.init_pose, op3.lower, op3.upper), None
    t, clipped, pos_clips, step_clips = 0.0, 0, 0, 0
    for _ in range(data.draw(st.integers(1, 10))):
        # Near the previous command, so that some joints pass unchanged and some are clipped.
        q = prev + data.draw(arrays(np.float64, n, elements=st.floats(-3, 3)))
        t += data.draw(st.sampled_from([period, period / 3, 5 * period]))
        sent = safe.send(JointCommand(q, t)).q
        dt = min(t - prev_t, period) if prev_t is not None else period
        step = op3.max_velocity * dt
        q_pos = np.clip(q, op3.lower, op3.upper)
        expected = np.clip(np.clip(q_pos, prev - step, prev + step), op3.lower, op3.upper)
        np.testing.assert_array_equal(sent, expected)
        clipped += int((q_pos != q).any() or (expected != q_pos).any())
        pos_clips += int((q_pos != q).sum())
        step_clips += int((expected != q_pos).sum())
        prev, prev_t = expected, t
    stats = safe.stats
    assert (stats.commands_clipped, stats.position_clips, stats.step_clips) == (
        clipped,
        pos_clips,
        step_clips,
    )


def test_nan_is_refused_and_nothing_sent(op3: RobotConfig) -> None:
    safe, inner = _layer(op3)
    q = op3.init_pose.copy()
    q[[1, 5]] = [np.nan, np.inf]
    with pytest.raises(UnsafeCommandError, match="NaN") as info:
        safe.send(JointCommand(q, 0.0))
    assert info.value.joints == (op3.joints[1].name, op3.joints[5].name)
    assert isinstance(info.value, HardwareError)
    assert inner.sent == []
    with pytest.raises(UnsafeCommandError, match="shape"):
        safe.send(JointCommand(np.zeros(3), 0.0))


def test_clip_statistics_and_report(op3: RobotConfig) -> None:
    safe, _ = _layer(op3)
    period = 1.0 / op3.control_rate_hz
    safe.send(JointCommand(op3.init_pose, 0.0))  # no clipping
    far = op3.init_pose.copy()
    far[0] = op3.upper[0] + 1.0
    safe.send(JointCommand(far, period))
    s = safe.stats
    assert (s.commands, s.commands_clipped, s.position_clips, s.step_clips) == (2, 1, 1, 1)
    assert s.max_position_excess_rad == pytest.approx(1.0)
    assert s.per_joint[op3.joints[0].name] == 1
    text = safe.report()
    assert "1 of 2 commands clipped" in text
    assert op3.joints[0].name in text


def test_in_range_commands_pass_unchanged(op3: RobotConfig) -> None:
    safe, _ = _layer(op3)
    q = op3.init_pose + 0.001
    sent = safe.send(JointCommand(q, 0.01))
    np.testing.assert_array_equal(sent.q, np.clip(q, op3.lower, op3.upper))
    assert safe.stats.step_clips == 0

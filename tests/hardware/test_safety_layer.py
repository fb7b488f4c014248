"""SafetyLayer: nothing outside the limits or the step bound ever reaches the backend."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robot_retarget.errors import HardwareError
from robot_retarget.hardware.safety import CLOCK_BUDGET_PERIODS, SafetyLayer, UnsafeCommandError
from robot_retarget.hardware.types import JointCommand
from robot_retarget.robot.config import RobotConfig
from robot_retarget.sim.backend import SimBackend
from tests.pipeline.scripted import FakeClock


def _layer(config: RobotConfig) -> tuple[SafetyLayer, SimBackend]:
    """A layer that keeps to the commands' stamps alone (no clock: the stamp bound's tests;
    the clock budget has its own below)."""
    inner = SimBackend(config, realtime=False)
    safe = SafetyLayer(config, inner, clock=None)
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
        q = data.draw(arrays(np.float64, n, elements=st.floats(-6.28, 6.28)))
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
        gap = t - prev_t if prev_t is not None else period
        dt = period if gap >= period * (1 - 1e-9) else gap  # a period to float rounding
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


def test_commands_sent_faster_than_their_stamps_are_held_to_the_time_that_passed(
    op3: RobotConfig,
) -> None:
    """A trajectory played in a loop that does not wait: stamps a period apart, a tenth of a
    period between the calls. Each joint moves no further than its velocity limit allows in
    the time that passed (plus the budget's periods), however the commands are stamped."""
    clock = FakeClock()
    inner = SimBackend(op3, realtime=False, clock=clock.now)
    safe = SafetyLayer(op3, inner, clock=clock.now)
    safe.connect()
    period = 1.0 / op3.control_rate_hz
    start = np.array(inner.read_state().q)
    target = np.where(start - op3.lower > op3.upper - start, op3.lower, op3.upper)
    t0 = clock.t
    for k in range(1, 101):
        clock.t += period / 10
        safe.send(JointCommand(target, k * period))
    moved = np.abs(np.array(inner.sent[-1].q) - start)
    allowed = op3.max_velocity * (clock.t - t0 + CLOCK_BUDGET_PERIODS * period) + 1e-9
    assert (moved <= allowed).all()
    # Stamps alone would have let each joint go ten times as far, or all the way.
    reach = np.minimum(np.abs(target - start), op3.max_velocity * 100 * period)
    assert (moved < reach - 0.1).all()
    assert safe.stats.clock_clips > 0
    assert "faster than real time" in safe.report()


def test_a_loop_at_its_rate_keeps_every_full_step(op3: RobotConfig) -> None:
    """The loop's ticks come late by up to most of a period and the next one early (it keeps
    its schedule): every command may still take a full period's step."""
    clock = FakeClock()
    inner = SimBackend(op3, realtime=False, clock=clock.now)
    safe = SafetyLayer(op3, inner, clock=clock.now)
    safe.connect()
    period = 1.0 / op3.control_rate_hz
    rng = np.random.default_rng(4)
    t0 = clock.t
    q = np.array(inner.read_state().q)
    direction = np.where(q - op3.lower > op3.upper - q, -1.0, 1.0)
    for k in range(1, 30):
        clock.t = t0 + k * period + rng.uniform(0.0, 0.9 * period)
        want = np.clip(q + direction * op3.max_velocity * period, op3.lower, op3.upper)
        q = np.array(safe.send(JointCommand(want, k * period * (1 + 1e-9))).q)
        np.testing.assert_allclose(q, want, atol=1e-12)
    assert safe.stats.clock_clips == 0


@settings(max_examples=60, deadline=None)
@given(st.data())
def test_no_window_of_time_sees_more_than_the_velocity_limit(
    op3: RobotConfig, data: st.DataObject
) -> None:
    """Whatever the stamps and the time between calls: between any two commands a joint moves
    at most v_max · (the time that passed + the budget's periods), and each command at most
    v_max · (its stamp step, at most a period)."""
    clock = FakeClock()
    inner = SimBackend(op3, realtime=False, clock=clock.now)
    safe = SafetyLayer(op3, inner, clock=clock.now)
    safe.connect()
    period = 1.0 / op3.control_rate_hz
    n = op3.num_joints
    times, qs = [clock.t], [np.array(inner.read_state().q)]
    stamp = 0.0
    for _ in range(data.draw(st.integers(1, 25))):
        clock.t += data.draw(st.sampled_from([0.0, period / 20, period / 2, period, 3 * period]))
        d_stamp = data.draw(st.sampled_from([period / 4, period, 10 * period]))
        stamp += d_stamp
        q = data.draw(arrays(np.float64, n, elements=st.floats(-4, 4)))
        sent = np.array(safe.send(JointCommand(q, stamp)).q)
        dt = period if len(qs) == 1 else min(d_stamp, period)  # the first: a period from connect
        assert (np.abs(sent - qs[-1]) <= op3.max_velocity * dt + 1e-9).all()
        times.append(clock.t)
        qs.append(sent)
    for i in range(len(qs)):
        for j in range(i + 1, len(qs)):
            allowed = op3.max_velocity * (times[j] - times[i] + CLOCK_BUDGET_PERIODS * period)
            allowed += 1e-9
            assert (np.abs(qs[j] - qs[i]) <= allowed).all()


def test_wrapped_round_a_connected_robot_the_first_step_is_bounded(op3: RobotConfig) -> None:
    """A layer put in front of a backend that is already connected (or reset to no pose) reads
    where the robot is and bounds the first step from there: it is not only clamped to the
    limits."""
    inner = SimBackend(op3, realtime=False)
    inner.connect()
    here = np.array(inner.read_state().q)
    safe = SafetyLayer(op3, inner, clock=None)
    period = 1.0 / op3.control_rate_hz
    sent = np.array(safe.send(JointCommand(op3.upper, 0.01)).q)
    assert (np.abs(sent - here) <= op3.max_velocity * period + 1e-9).all()
    safe.reset(None)
    there = np.array(inner.read_state().q)  # where the servos got to, not the last goal
    again = np.array(safe.send(JointCommand(op3.lower, 0.02)).q)
    assert (np.abs(again - there) <= op3.max_velocity * period + 1e-9).all()


def test_a_command_time_that_is_not_a_finite_number_is_refused(op3: RobotConfig) -> None:
    from robot_retarget.errors import InvalidCommandError

    for bad in (float("inf"), float("nan"), -float("inf")):
        with pytest.raises(InvalidCommandError, match="finite number of seconds"):
            JointCommand(op3.init_pose, bad)
    with pytest.raises(ValueError, match="one value per joint"):  # still a ValueError too
        JointCommand(np.zeros((2, op3.num_joints)), 0.0)


def test_a_trajectory_at_the_velocity_limit_stamped_k_over_rate_is_not_clipped(
    op3: RobotConfig,
) -> None:
    """Stamps k / rate lose a few ulps far from 0; steps of exactly v_max / rate (what the
    optimizer writes at a limb's top speed) were counted as clipped by 1e-16 rad."""
    safe, inner = _layer(op3)
    rate = op3.control_rate_hz
    q = np.array(inner.read_state().q)
    direction = np.where(q - op3.lower > op3.upper - q, -1.0, 1.0)
    for k in range(1000, 1040):
        q = np.clip(q + direction * op3.max_velocity / rate, op3.lower, op3.upper)
        sent = safe.send(JointCommand(q, k / rate))
        np.testing.assert_array_equal(sent.q, q)
    assert safe.stats.commands_clipped == 0


def test_two_threads_sending_at_once_are_taken_one_at_a_time(op3: RobotConfig) -> None:
    """While one send is on its way to the servos, another waits: it is clamped against the
    command that went out, not against the one before it."""
    import threading

    entered, release = threading.Event(), threading.Event()

    class SlowBackend(SimBackend):
        def send(self, cmd: JointCommand) -> JointCommand:
            entered.set()
            release.wait(5.0)
            return super().send(cmd)

    inner = SlowBackend(op3, realtime=False)
    safe = SafetyLayer(op3, inner, clock=None)
    safe.connect()
    q = np.array(inner.read_state().q)
    first = threading.Thread(target=safe.send, args=(JointCommand(q, 0.01),))
    first.start()
    assert entered.wait(5.0)
    second = threading.Thread(target=safe.send, args=(JointCommand(q + 1.0, 0.02),))
    second.start()
    second.join(0.2)
    assert second.is_alive()
    assert safe.stats.commands == 1
    release.set()
    first.join(5.0)
    second.join(5.0)
    assert safe.stats.commands == 2
    step = np.abs(np.array(inner.sent[-1].q) - np.array(inner.sent[-2].q))
    assert (step <= op3.max_velocity * 0.01 + 1e-12).all()


def test_a_command_beyond_a_turn_is_refused_as_other_units(op3: RobotConfig) -> None:
    """Degrees given as radians: clamping them had driven every joint to a limit at full speed,
    reported only as position clips. Refused by name; nothing sent; the layer goes on."""
    safe, inner = _layer(op3)
    before = len(inner.sent)
    degrees = np.degrees(op3.init_pose)
    with pytest.raises(UnsafeCommandError, match=r"beyond a turn .*degrees\?") as info:
        safe.send(JointCommand(degrees, 0.01))
    far = np.abs(degrees) > 2 * np.pi
    assert far.any()
    assert info.value.joints == tuple(n for n, f in zip(op3.joint_names, far, strict=True) if f)
    assert len(inner.sent) == before
    safe.send(JointCommand(op3.init_pose, 0.02))

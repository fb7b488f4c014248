"""The control loop's one-slot mailbox for a watcher (stream --view): one frame per command,
the same command the backend got, and a watcher that never makes the loop wait."""

from __future__ import annotations

import numpy as np

from robot_retarget.motion.human_motion import HumanMotion
from robot_retarget.pipeline.live_mailbox import LiveFrame, Mailbox
from robot_retarget.pipeline.loop import ControlLoop, LoopSettings
from robot_retarget.pipeline.step import RetargetStep
from robot_retarget.robot.config import RobotConfig
from robot_retarget.sim.backend import SimBackend
from robot_retarget.sources.replay import ReplaySource
from tests.pipeline.scripted import FakeClock


class KeepingMailbox(Mailbox[LiveFrame]):
    """A mailbox that also remembers everything put, to compare with the loop's log."""

    def __init__(self) -> None:
        super().__init__()
        self.all: list[LiveFrame] = []

    def put(self, item: LiveFrame) -> None:
        super().put(item)
        self.all.append(item)


def test_newest_item_wins_and_reading_keeps_it() -> None:
    box: Mailbox[int] = Mailbox()
    assert box.latest() is None
    box.put(1)
    box.put(2)
    assert box.latest() == 2
    assert box.latest() == 2


def test_the_loop_posts_every_command_it_sends(
    step: RetargetStep, demo: HumanMotion, op3: RobotConfig
) -> None:
    clock = FakeClock()
    box = KeepingMailbox()
    loop = ControlLoop(step, ReplaySource(demo.frames(0, 31)), SimBackend(op3, clock=clock.now),
                       LoopSettings(ramp_speed_fraction=1.0), record=True, clock=clock.now,
                       sleep=clock.sleep, mailbox=box)  # fmt: skip
    result = loop.run()
    assert len(box.all) == len(result.log) == result.stats.commands
    for frame, entry in zip(box.all, result.log, strict=True):
        np.testing.assert_array_equal(frame.q_cmd, entry.q)
        assert frame.mode == entry.mode.value
        assert frame.t_s == entry.t_s
    assert box.latest() is box.all[-1]
    assert box.all[-1].mode == "stopping"
    # The safety layer's count is what the frames show: a frame whose target and command
    # differ is a clipped command.
    clipped = sum(bool(np.any(f.q_target != f.q_cmd)) for f in box.all)
    assert clipped == result.safety.commands_clipped == box.all[-1].commands_clipped
    counts = [f.commands_clipped for f in box.all]
    assert counts == sorted(counts)
    latencies = [f.latency_s for f in box.all if np.isfinite(f.latency_s)]
    assert latencies
    assert min(latencies) >= 0.0


def test_frames_handed_over_are_never_written_again(
    step: RetargetStep, demo: HumanMotion, op3: RobotConfig
) -> None:
    clock = FakeClock()
    box = KeepingMailbox()
    loop = ControlLoop(step, ReplaySource(demo.frames(0, 16)), SimBackend(op3, clock=clock.now),
                       clock=clock.now, sleep=clock.sleep, mailbox=box)  # fmt: skip
    snapshots: list[np.ndarray] = []
    original_put = box.put

    def put_and_copy(item: LiveFrame) -> None:
        original_put(item)
        snapshots.append(item.q_cmd.copy())

    box.put = put_and_copy  # type: ignore[method-assign]
    loop.run()
    for frame, copy in zip(box.all, snapshots, strict=True):
        np.testing.assert_array_equal(frame.q_cmd, copy)  # the watcher reads what was sent

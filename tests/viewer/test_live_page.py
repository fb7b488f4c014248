"""The live page shows the loop's newest frame, names clipped joints, and stream --view runs."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.cli import stream_cmd
from robot_retarget.pipeline.live_mailbox import LiveFrame, Mailbox
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.viewer.live_page import LivePage

pytest.importorskip("viser", reason="the viewer needs the [view] extra (pip install viser)")

TIME_LIMIT_S = 90
FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"
OP3 = load_robot_config("op3")


def wait_until_published(page: LivePage, count: int, timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while page.published < count:
        if time.monotonic() > deadline:
            pytest.fail(f"the page published {page.published} frames, expected {count}")
        time.sleep(0.01)


def frame(t_s: float, q_target: np.ndarray, q_cmd: np.ndarray, clipped: int) -> LiveFrame:
    return LiveFrame(t_s, "tracking", q_target, q_cmd, 0.004, 0.0075, 0.0002, clipped)


def test_the_newest_frame_is_shown_with_the_clipped_joints() -> None:
    box: Mailbox[LiveFrame] = Mailbox()
    measured = OP3.init_pose + 0.01
    with LivePage(OP3, box, measure=lambda: measured, port=0) as page:
        q = OP3.init_pose.copy()
        box.put(frame(1.0, q, q, 0))
        wait_until_published(page, 1)
        assert page.shown()["Clipped now"] == "-"
        over = q.copy()
        over[3] = OP3.upper[3] + 0.5  # the pipeline asked past the limit; the command is clamped
        box.put(frame(1.008, over, np.minimum(over, OP3.upper), 7))
        wait_until_published(page, 2)
        shown = page.shown()
    assert shown["Clipped now"] == OP3.joint_names[3]
    assert shown["Safety: commands clipped"] == "7"
    assert shown["Mode"] == "tracking"
    assert shown["Latency (ms)"] == "7.50"


def test_a_frame_is_published_once() -> None:
    box: Mailbox[LiveFrame] = Mailbox()
    with LivePage(OP3, box, port=0, publish_hz=30.0) as page:
        box.put(frame(0.0, OP3.init_pose, OP3.init_pose, 0))
        wait_until_published(page, 1)
        time.sleep(0.2)  # several publish periods: the same frame is not drawn again
        assert page.published == 1


def test_stream_with_view_serves_the_page(capsys: pytest.CaptureFixture[str]) -> None:
    parser = argparse.ArgumentParser()
    stream_cmd.configure(parser)
    args = parser.parse_args(
        ["--robot", "op3", "--source", f"replay:{FIXTURES / 'tiny_walk.bvh'}", "--backend",
         "sim", "--duration", "1.0", "--view", "--view-port", "0", "--no-browser"]
    )  # fmt: skip
    assert stream_cmd.run(args) == 0
    err = capsys.readouterr().err
    assert "live view: http://127.0.0.1:" in err
    assert "[ramp-in]" in err

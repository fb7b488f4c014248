"""``stream --source udp-keypoints://``: 2D keypoint packets drive the simulator through the
same control loop and safety layer; remote binds follow the 3D UDP source's rules."""

from __future__ import annotations

import argparse
import socket
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.cli import stream_cmd
from robot_retarget.errors import SourceError
from robot_retarget.keypoints.demo_2d import demo_keypoints
from robot_retarget.motion.synthetic import demo_motion
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.pipeline.convert import check_limits
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.sources.keypoints.wire import encode_keypoints

TIME_LIMIT_S = 90


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    stream_cmd.configure(parser)
    return parser.parse_args(list(argv))


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_remote_keypoint_sources_need_permission_and_a_token() -> None:
    with pytest.raises(SourceError, match="allow-remote"):
        stream_cmd.run(_args("--source", "udp-keypoints://0.0.0.0:9751"))
    with pytest.raises(SourceError, match="--allow-remote without --token"):
        stream_cmd.run(_args("--source", "udp-keypoints://0.0.0.0:9751", "--allow-remote"))


def test_no_image_planes_is_refused_without_a_keypoint_source() -> None:
    from robot_retarget.errors import RetargetError

    with pytest.raises(RetargetError, match="--no-image-planes is about the 2D keypoints"):
        stream_cmd.run(_args("--source", "udp://127.0.0.1:9750", "--no-image-planes"))


def test_image_size_is_checked_and_refused_without_a_keypoint_source() -> None:
    from robot_retarget.errors import RetargetError

    assert _args("--source", "udp-keypoints://", "--image-size", "1280x720").image_size == (
        1280.0,
        720.0,
    )
    for bad in ("1280", "1280x0", "wide", "-5x3"):
        with pytest.raises(SystemExit):
            _args("--source", "udp-keypoints://", "--image-size", bad)
    with pytest.raises(RetargetError, match="--image-size is about the camera"):
        stream_cmd.run(_args("--source", "udp://127.0.0.1:9750", "--image-size", "640x480"))


def _wait_until_bound(port: int, stop: threading.Event, timeout_s: float = 60.0) -> None:
    """Return once something listens on UDP ``port`` (binding it ourselves fails)."""
    deadline = time.monotonic() + timeout_s
    while not stop.is_set() and time.monotonic() < deadline:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            try:
                probe.bind(("127.0.0.1", port))
            except OSError:
                return
        time.sleep(0.01)


def test_keypoint_packets_drive_the_simulator(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    port = _free_port()
    seq = demo_keypoints(demo_motion(fps=30.0).frames(0, 90))
    people = np.concatenate([np.nan_to_num(seq.xy), seq.confidence[..., None]], axis=-1)
    stop = threading.Event()

    def send() -> None:
        _wait_until_bound(port, stop)  # a packet sent before the stream listens is lost
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
            t0 = time.monotonic()
            for i in range(people.shape[0]):
                if stop.is_set():
                    return
                packet = encode_keypoints(i + 1, time.monotonic() - t0, [people[i]], token="k")
                tx.sendto(packet, ("127.0.0.1", port))
                time.sleep(1.0 / 30.0)

    sender = threading.Thread(target=send, daemon=True)
    record = tmp_path / "streamed.npz"
    sender.start()
    try:
        args = _args("--robot", "op3", "--source", f"udp-keypoints://127.0.0.1:{port}",
                     "--token", "k", "--backend", "sim", "--duration", "3.5",
                     "--record", str(record))  # fmt: skip
        assert stream_cmd.run(args) == 0
    finally:
        stop.set()
        sender.join(timeout=5)
    traj = RobotTrajectory.read(record)
    config = load_robot_config("op3")
    assert check_limits(config, traj.q, 1 / traj.fps, q_start=config.init_pose).ok
    out = capsys.readouterr()
    assert "source: 90 received, 90 accepted, 0 dropped" in out.out
    assert "image planes: camera estimated at" in out.out
    # Nothing past a limit or a stamp's step. Steps held to the wall clock are not asserted:
    # on a loaded machine they are the safety layer doing its job (tests/pipeline/
    # test_loop_under_load.py pins that a loop at its rate is never held back).
    assert "(0 joint limit clips" in out.out
    assert "; 0 velocity clips" in out.out
    # The performer's arm movements reached the robot (not a robot held in one pose).
    late = np.asarray(traj.q)[len(traj.q) // 2 :]
    assert float(np.ptp(late, axis=0).max()) > 0.2

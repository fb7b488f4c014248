"""``stream``: replay into the simulator, refused sources, and Ctrl-C with the real SDK on a
simulated Dynamixel bus (the bus must see the torque go off)."""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.cli import stream_cmd
from robot_retarget.cli.output_paths import OutputPathError
from robot_retarget.cli.port_args import PortNotFoundError
from robot_retarget.errors import HardwareError, SourceError
from robot_retarget.motion.trajectory import RobotTrajectory
from robot_retarget.pipeline.convert import check_limits
from robot_retarget.robot.loader import load_robot_config
from robot_retarget.sim.robot_bus import SimulatedRobotBus

REPO = Path(__file__).resolve().parents[2]
FIXTURES = REPO / "tests" / "fixtures" / "motion"
TIME_LIMIT_S = 90


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    stream_cmd.configure(parser)
    return parser.parse_args(list(argv))


def test_replay_into_the_simulator(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    record = tmp_path / "streamed.csv"
    args = _args("--robot", "op3", "--source", f"replay:{FIXTURES / 'tiny_walk.bvh'}",
                 "--backend", "sim", "--duration", "1.0", "--stats-every", "0.5",
                 "--record", str(record))  # fmt: skip
    assert stream_cmd.run(args) == 0
    traj = RobotTrajectory.read(record)
    config = load_robot_config("op3")
    assert traj.num_frames > 100
    assert check_limits(config, traj.q, 1 / traj.fps, q_start=config.init_pose).ok
    with pytest.raises(OutputPathError, match="--force"):
        stream_cmd.run(args)
    out = capsys.readouterr()
    assert "latency median" in out.out
    # Nothing past a limit or a stamp's step. Steps held to the wall clock are not asserted:
    # on a loaded machine they are the safety layer doing its job (tests/pipeline/
    # test_loop_under_load.py pins that a loop at its rate is never held back).
    assert "(0 joint limit clips" in out.out
    assert "; 0 velocity clips" in out.out
    assert "solver fallbacks: 0" in out.out
    assert "[ramp-in]" in out.err
    assert "streaming replay" in out.err


def test_a_stream_that_never_gets_input_says_so_and_fails(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # a port nobody sends to (freed for the stream)
    record = tmp_path / "none.csv"
    args = _args("--robot", "op3", "--source", f"udp://127.0.0.1:{port}", "--backend", "sim",
                 "--duration", "0.5", "--record", str(record))  # fmt: skip
    assert stream_cmd.run(args) == 1
    out = capsys.readouterr()
    assert "nan" not in out.out
    assert "no input frame arrived" in out.out
    assert "no input frame from udp://" in out.err
    assert "is the sender running" in out.err
    assert not record.exists()  # nothing streamed, nothing recorded


@pytest.mark.parametrize(
    ("source", "match"),
    [("udp://0.0.0.0:9750", "allow-remote"), ("tcp-bvh://192.168.3.3:7001", "allow-remote"),
     ("bogus:thing", "unknown source")],
)  # fmt: skip
def test_unsafe_or_unknown_sources_are_refused(source: str, match: str) -> None:
    with pytest.raises(SourceError, match=match):
        stream_cmd.run(_args("--source", source))


@pytest.mark.usefixtures("no_work")
def test_allow_remote_needs_a_token_or_an_explicit_insecure_flag(tmp_path: Path) -> None:
    for source in ("udp://0.0.0.0:9750", "tcp-bvh://192.168.3.3:7001"):
        with pytest.raises(SourceError, match="--allow-remote without --token"):
            stream_cmd.run(_args("--source", source, "--allow-remote"))
    with pytest.raises(SourceError, match="udp:// sources only"):
        stream_cmd.run(_args("--source", "tcp-bvh://192.168.3.3:7001", "--allow-remote",
                             "--token", "s3cret"))  # fmt: skip
    with pytest.raises(SourceError, match="contradict"):
        stream_cmd.run(_args("--source", "udp://0.0.0.0:0", "--allow-remote", "--token", "s",
                             "--insecure-no-token"))  # fmt: skip
    # Accepted either way: the next check (the --record folder) is the one that refuses.
    missing = str(tmp_path / "missing" / "r.npz")
    for extra in (["--token", "s3cret"], ["--insecure-no-token"]):
        with pytest.raises(OutputPathError, match="no such folder"):
            stream_cmd.run(_args("--source", "udp://0.0.0.0:0", "--allow-remote", *extra,
                                 "--record", missing))  # fmt: skip


@pytest.mark.usefixtures("no_work")
def test_record_path_is_checked_before_the_robot_moves(tmp_path: Path, read_only_dir: Path) -> None:
    clip = f"replay:{FIXTURES / 'tiny_walk.bvh'}"
    with pytest.raises(OutputPathError, match=r"--record .*no such folder"):
        stream_cmd.run(_args("--source", clip, "--record", str(tmp_path / "nope" / "r.npz")))
    with pytest.raises(OutputPathError, match=r"--record .*not writable"):
        stream_cmd.run(_args("--source", clip, "--record", str(read_only_dir / "r.npz")))
    with pytest.raises(OutputPathError, match="must end in"):
        stream_cmd.run(_args("--source", clip, "--record", str(tmp_path / "r.bvh")))
    (tmp_path / "r.npz").write_text("an earlier take")
    with pytest.raises(OutputPathError, match="--force"):
        stream_cmd.run(_args("--source", clip, "--record", str(tmp_path / "r.npz")))
    assert (tmp_path / "r.npz").read_text() == "an earlier take"


def test_recording_is_saved_elsewhere_when_its_folder_fails_at_the_end(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from robot_retarget.pipeline.loop import ControlLoop, LoopResult

    session = tmp_path / "session"
    session.mkdir()
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    run_loop = ControlLoop.run

    def run_then_lose_the_folder(self: ControlLoop) -> LoopResult:
        result = run_loop(self)
        shutil.rmtree(session)  # the folder went away while the robot moved
        return result

    monkeypatch.setattr(ControlLoop, "run", run_then_lose_the_folder)
    args = _args("--source", f"replay:{FIXTURES / 'tiny_walk.bvh'}", "--duration", "0.3",
                 "--record", str(session / "take.csv"))  # fmt: skip
    assert stream_cmd.run(args) == 0
    saved = list(work.glob("take-*.csv"))
    assert len(saved) == 1
    assert RobotTrajectory.read(saved[0]).num_frames > 10
    out = capsys.readouterr()
    rows = RobotTrajectory.read(saved[0]).num_frames
    assert f"to {saved[0]} ({rows} rows at 125 Hz)" in out.out
    assert f"saved to {saved[0]} instead" in out.err


def test_source_warnings_are_reported_live(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from robot_retarget.pipeline.loop import ControlLoop, LoopResult

    run_loop = ControlLoop.run

    def warn_then_run(self: ControlLoop) -> LoopResult:
        self.source.stats.warn("source: 30 packets in a row dropped as out of order")
        return run_loop(self)

    monkeypatch.setattr(ControlLoop, "run", warn_then_run)
    args = _args("--source", f"replay:{FIXTURES / 'tiny_walk.bvh'}", "--duration", "0.2")
    assert stream_cmd.run(args) == 0
    out = capsys.readouterr()
    assert "source: 30 packets in a row dropped as out of order" in out.err  # live
    assert "1 warning(s)" in out.out  # and in the source's summary at exit


@pytest.mark.usefixtures("no_work")
def test_ports_use_the_bus_syntax_and_must_exist() -> None:
    clip = f"replay:{FIXTURES / 'tiny_walk.bvh'}"
    with pytest.raises(PortNotFoundError, match="/dev/nonexistent does not exist"):
        stream_cmd.run(_args("--source", clip, "--backend", "dynamixel",
                             "--port", "/dev/nonexistent"))  # fmt: skip
    with pytest.raises(HardwareError, match="give --port BUS=PATH"):
        stream_cmd.run(_args("--robot", "poppy_humanoid", "--source", clip,
                             "--backend", "dynamixel", "--port", "/dev/null"))  # fmt: skip
    with pytest.raises(HardwareError, match="no bus 'legs'"):
        stream_cmd.run(_args("--robot", "poppy_humanoid", "--source", clip,
                             "--backend", "dynamixel", "--port", "legs=/dev/null"))  # fmt: skip


def test_a_default_port_that_cannot_be_opened_says_where_it_came_from(
    missing_default_ports: Path,
) -> None:
    """A bus no --port names opens the config's default_port: the error says so, not only
    "cannot open" a path the user never typed."""
    tmp_path = missing_default_ports
    clip = f"replay:{FIXTURES / 'tiny_walk.bvh'}"
    lower = tmp_path / "tty_lower_body"
    controller, terminal = os.openpty()  # a port upper_body can open
    upper = os.ttyname(terminal)
    try:
        with pytest.raises(HardwareError, match="cannot open serial port") as e:
            stream_cmd.run(_args("--robot", "poppy_humanoid", "--source", clip, "--backend",
                                 "dynamixel", "--port", f"upper_body={upper}"))  # fmt: skip
    finally:
        os.close(controller)
        os.close(terminal)
    assert f"{lower} is the robot config's default port for bus lower_body" in str(e.value)
    assert "give --port lower_body=PATH" in str(e.value)
    with pytest.raises(HardwareError, match="give --port PATH;"):
        stream_cmd.run(_args("--robot", "op3", "--source", clip, "--backend", "dynamixel"))


def test_a_smoothed_replay_stays_within_the_limits(tmp_path: Path) -> None:
    """``--one-euro``: the loop smooths its input; every command is still inside the limits."""
    record = tmp_path / "smoothed.npz"
    args = _args("--robot", "op3", "--source", f"replay:{FIXTURES / 'tiny_walk.bvh'}",
                 "--backend", "sim", "--duration", "1.0", "--one-euro", "2,0.3",
                 "--record", str(record))  # fmt: skip
    assert args.one_euro.min_cutoff_hz == 2.0
    assert stream_cmd.run(args) == 0
    traj = RobotTrajectory.read(record)
    config = load_robot_config("op3")
    assert check_limits(config, traj.q, 1 / traj.fps, q_start=config.init_pose).ok
    with pytest.raises(SystemExit):
        _args("--source", "udp://127.0.0.1:0", "--one-euro", "2")


def test_raw_positions_reaches_the_udp_source(monkeypatch: pytest.MonkeyPatch) -> None:
    """``--raw-positions``: the UDP source solves position packets as sent."""
    import robot_retarget.sources as sources

    seen: list[bool] = []

    class OpenedError(Exception):
        pass

    def fake_open_source(spec: str, **kwargs: object) -> None:
        seen.append(bool(kwargs["clean_positions"]))
        raise OpenedError

    monkeypatch.setattr(sources, "open_source", fake_open_source)
    for flags, clean in (((), True), (("--raw-positions",), False)):
        with pytest.raises(OpenedError):
            stream_cmd.run(_args("--source", "udp://127.0.0.1:0", *flags))
        assert seen[-1] is clean
    from robot_retarget.errors import RetargetError

    with pytest.raises(RetargetError, match="--raw-positions is about the position packets"):
        stream_cmd.run(_args("--source", f"replay:{FIXTURES / 'tiny_walk.bvh'}", "--raw-positions"))
    assert len(seen) == 2  # refused before the source was opened


def test_a_trajectory_as_model_says_what_to_pass(tmp_path: Path) -> None:
    from robot_retarget.errors import ModelLoadError

    trajectory = RobotTrajectory(("a",), np.zeros((2, 1)), 125.0).write(tmp_path / "t.npz")
    clip = f"replay:{FIXTURES / 'tiny_walk.bvh'}"
    for model in (str(FIXTURES / "tiny_walk.bvh"), str(trajectory)):
        with pytest.raises(ModelLoadError, match=r"not a model: give --model a model name"):
            stream_cmd.run(_args("--source", clip, "--model", model))


_CHILD = (
    "import argparse, sys\n"
    "from robot_retarget.cli import stream_cmd as c\n"
    "p = argparse.ArgumentParser(); c.configure(p)\n"
    "sys.exit(c.run(p.parse_args(sys.argv[1:])))\n"
)


@pytest.mark.parametrize(("stop", "said"), [(signal.SIGINT, "Ctrl-C"), (signal.SIGTERM, "SIGTERM")])
def test_ctrl_c_stops_smoothly_and_the_bus_sees_torque_off(stop: int, said: str) -> None:
    """Ctrl-C, or SIGTERM from a service manager: the same smooth stop, reported as itself."""
    config = load_robot_config("op3")
    with SimulatedRobotBus(config, config.init_pose) as sim:
        port = sim.ports["main"]
        cmd = [sys.executable, "-c", _CHILD, "--robot", "op3", "--backend", "dynamixel",
               "--port", port, "--source", f"replay:{FIXTURES / 'tiny_walk.bvh'}", "--loop",
               "--stats-every", "1"]  # fmt: skip
        env = dict(os.environ, PYTHONPATH=str(REPO))
        proc = subprocess.Popen(
            cmd, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        try:
            deadline = time.monotonic() + 60.0
            while not all(sim.torque_on()) and time.monotonic() < deadline:
                if proc.poll() is not None:
                    break
                time.sleep(0.05)
            assert all(sim.torque_on()), "the stream never switched the torque on"
            time.sleep(1.0)  # stream for a while
            moved_from_init = float(np.max(np.abs(sim.goal_q() - config.init_pose)))
            proc.send_signal(stop)
            out, err = proc.communicate(timeout=30.0)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
        sim.settle()
        torque = sim.torque_on()
        goal = sim.goal_q()
    assert proc.returncode == 0, err
    assert f"stopped by {said}: torque off" in out
    assert "interrupted: stopping smoothly" in err
    assert moved_from_init > 0.01
    assert not any(torque)
    np.testing.assert_allclose(goal, config.safe_pose, atol=0.002)  # ramped there first


def test_tcp_bvh_stream_drives_the_simulator(capsys: pytest.CaptureFixture[str]) -> None:
    """A BVH broadcast (header, then one line per frame at 30 fps) from a local server."""
    text = (FIXTURES / "tiny_walk.bvh").read_text()
    head, _, motion = text.partition("MOTION")
    lines = motion.strip().splitlines()
    header = (head + "MOTION\n" + lines[0] + "\n" + lines[1] + "\n").encode()
    rows = [(ln + "\n").encode() for ln in lines[2:]]
    srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)
    srv.settimeout(20.0)

    def serve() -> None:
        try:
            conn, _ = srv.accept()
        except OSError:
            return
        with conn:
            conn.sendall(header)
            for row in rows * 2:
                time.sleep(1 / 30)
                try:
                    conn.sendall(row)
                except OSError:
                    return

    server = threading.Thread(target=serve, daemon=True)
    server.start()
    try:
        port = srv.getsockname()[1]
        args = _args("--source", f"tcp-bvh://127.0.0.1:{port}", "--duration", "1.2")
        assert stream_cmd.run(args) == 0
    finally:
        srv.close()
        server.join(timeout=5.0)
    out = capsys.readouterr().out
    assert "0 dropped" in out
    assert "modes: ramp-in" in out  # 1.2 s: the ramped start may still be catching up
    retargeted = int(out.split("frames: ")[1].split(" retargeted")[0])
    assert retargeted > 20


def test_second_ctrl_c_switches_off_at_once() -> None:
    config = load_robot_config("op3")
    with SimulatedRobotBus(config, config.init_pose) as sim:
        clip = FIXTURES / "tiny_walk.bvh"
        cmd = [sys.executable, "-c", _CHILD, "--backend", "dynamixel", "--port",
               sim.ports["main"], "--source", f"replay:{clip}", "--loop"]  # fmt: skip
        env = dict(os.environ, PYTHONPATH=str(REPO))
        proc = subprocess.Popen(
            cmd, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        try:
            deadline = time.monotonic() + 60.0
            while not all(sim.torque_on()) and time.monotonic() < deadline:
                if proc.poll() is not None:
                    break
                time.sleep(0.05)
            assert all(sim.torque_on()), "the stream never switched the torque on"
            time.sleep(0.5)
            proc.send_signal(signal.SIGINT)
            time.sleep(0.05)  # now in the smooth stop (≈ 1 s to the safe pose)
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=30.0)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
        sim.settle()
        torque = sim.torque_on()
    assert proc.returncode == 0, err
    # Said apart from a smooth stop: the robot was not brought to the safe pose.
    assert "stopped by Ctrl-C twice: the move to the safe pose was cut short" in out
    assert "interrupted: stopping smoothly" in err
    assert not any(torque)


def test_a_recording_survives_an_error_that_stops_the_stream(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The bus fails mid-session: the error still reaches the user, and so does what was sent."""
    from robot_retarget.errors import HardwareError
    from robot_retarget.pipeline import backends
    from robot_retarget.sim.backend import SimBackend

    class Unplugged(SimBackend):
        def send(self, cmd):  # type: ignore[no-untyped-def]
            if len(self.sent) >= 40:
                raise HardwareError("bus unplugged")
            return super().send(cmd)

    monkeypatch.setattr(backends, "open_backend", lambda config, *_, **__: Unplugged(config))
    record = tmp_path / "partial.npz"
    args = _args("--robot", "op3", "--source", f"replay:{FIXTURES / 'tiny_walk.bvh'}",
                 "--backend", "sim", "--duration", "2.0", "--record", str(record))  # fmt: skip
    with pytest.raises(HardwareError, match="unplugged"):
        stream_cmd.run(args)
    assert abs(RobotTrajectory.read(record).num_frames - 40) <= 2  # 40 ticks on the 125 Hz grid
    assert f"recorded 40 commands to {record}" in capsys.readouterr().out


def test_a_recording_is_on_its_rate_s_grid_whatever_the_ticks() -> None:
    """--wake-on-input's early ticks (and missed ones) had been written a row each at the
    nominal rate: an 8 s stream became 14.85 s at 20 Hz."""
    rate = 20.0
    t = np.array([0.0, 0.05, 0.06, 0.08, 0.1, 0.1, 0.25, 0.3])  # early, repeated, missed
    q = np.stack([t * 2.0, -t], axis=1)  # a joint at 2 rad/s, another at -1 rad/s
    rows = stream_cmd.on_the_rate_grid(t + 7.0, q, rate)
    assert rows.shape == (7, 2)  # 0 … 0.3 s at 20 Hz
    np.testing.assert_allclose(rows[:, 0], np.arange(7) / rate * 2.0, atol=1e-12)
    assert np.all(np.abs(np.diff(rows, axis=0)) <= np.array([2.0, 1.0]) / rate + 1e-12)


def test_a_rate_the_loop_did_not_keep_is_warned_of() -> None:
    from robot_retarget.cli.stream_cmd import overrun_warning

    assert overrun_warning(0, 0, 125.0, rate_given=False) is None  # no tick at all
    # 1.6 %: a tcp-bvh stream's start, at the config's rate (a review had this warned of)
    assert overrun_warning(12, 750, 125.0, rate_given=False) is None
    warning = overrun_warning(14903, 10200, 10000.0, rate_given=True)
    assert warning is not None
    assert "overran 14903 of 25103 ticks (59%)" in warning
    assert "did not keep 10000 Hz" in warning
    assert "use a lower --rate" in warning
    own = overrun_warning(100, 650, 125.0, rate_given=False)
    assert own is not None
    assert "--rate" not in own  # the user passed none
    assert "the robot config's control rate" in own


def test_the_simulator_refuses_a_rate_the_servos_would(capsys: pytest.CaptureFixture[str]) -> None:
    """2000 Hz leaves OP3's shoulders 1.57 ticks per period: the Dynamixel backend refuses it
    on connecting, and so does the simulator, before anything opens (it used to run)."""
    from robot_retarget.hardware.safety import UnsafeCommandError

    clip = f"replay:{FIXTURES / 'tiny_walk.bvh'}"
    for backend in ("sim", "dynamixel"):
        with pytest.raises(UnsafeCommandError, match=r"at 2000 Hz .*run at 1570 Hz or less"):
            stream_cmd.run(_args("--source", clip, "--backend", backend, "--rate", "2000"))
    assert capsys.readouterr().err == ""  # refused before the stream's first line


def test_a_stream_on_port_0_names_its_port_and_a_record_it_skipped(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Port 0: the banner names the port the system chose, the source being bound before the
    robot connects (it said ':0'), and with no sender the --record path is said not to be
    written."""
    record = tmp_path / "rec.npz"
    argv = ["--source", "udp://127.0.0.1:0", "--duration", "0.3", "--record", str(record)]
    assert stream_cmd.run(_args(*argv)) == 1
    err = capsys.readouterr().err
    port = int(err.split("streaming udp://127.0.0.1:")[1].split()[0])
    assert port > 0
    assert f"no input frame from udp://127.0.0.1:{port}" in err
    assert f"nothing recorded: {record} not written" in err
    assert not record.exists()


def test_a_source_that_cannot_bind_is_said_before_the_robot_connects(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The bind error comes first: no banner, and the backend is never connected (it was
    connected, then the source failed)."""
    from robot_retarget.sim.backend import SimBackend

    def refuse(self: SimBackend) -> None:
        raise AssertionError("the robot was connected before the source was bound")

    monkeypatch.setattr(SimBackend, "connect", refuse)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        with pytest.raises(SourceError, match="is another stream running"):
            stream_cmd.run(_args("--source", f"udp://127.0.0.1:{port}", "--duration", "0.3"))
    assert "streaming" not in capsys.readouterr().err


def test_a_stream_that_ends_before_the_robot_reached_the_motion_says_so(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A replay that ends during the start ramp: safe, but the motion was never tracked, and
    the run had ended as if it had played ("modes: ramp-in, stopping", no word)."""
    args = _args("--robot", "op3", "--source", f"replay:{FIXTURES / 'tiny_walk.bvh'}",
                 "--backend", "sim", "--duration", "0.3")  # fmt: skip
    assert stream_cmd.run(args) == 0
    out = capsys.readouterr()
    assert "tracking" not in out.out.split("modes:")[1]
    assert "never tracked the motion" in out.err
    args = _args("--robot", "op3", "--source", f"replay:{FIXTURES / 'tiny_walk.bvh'}",
                 "--backend", "sim", "--duration", "3.5", "--loop")  # fmt: skip
    assert stream_cmd.run(args) == 0
    out = capsys.readouterr()
    assert "tracking" in out.out.split("modes:")[1]
    assert "never tracked" not in out.err

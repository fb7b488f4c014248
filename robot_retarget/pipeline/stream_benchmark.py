"""``bench stream``: the live stream's timing on the simulated Dynamixel bus, with and without
a watched ``--view`` page.

Each run streams the built-in demo clip (replayed in a loop) through the control loop, the real
dynamixel-sdk and the simulated bus on a pty (as ``demo`` does) for ``--seconds``, at ``--rate``
(default 125 Hz), and reports the loop's late input frames, held ticks, overruns and tick jitter
(how late each tick started: median and p99). ``--view`` adds the same run with the live page
(:mod:`robot_retarget.viewer.live_page`) fed from the loop's mailbox and watched by a client in
its own process: ``--client ws`` (default) reads the page's websocket as a browser does without
rendering; ``--client chromium`` opens the page in headless Chromium (which also renders, on the
same CPUs); ``--client none`` serves the page unwatched. Variants alternate, ``--repeats``
times, so a busy machine's drift hits both alike.
"""

from __future__ import annotations

import argparse
import select
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from robot_retarget.number_args import positive_float, positive_int
from robot_retarget.pipeline.defaults import MODEL_HELP

HELP = "Live stream on the simulated bus: late frames and tick jitter, with and without --view."


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="op3", help="robot config name or YAML path")
    parser.add_argument("--model", help=MODEL_HELP)
    parser.add_argument("--rate", type=positive_float, default=125.0, help="control rate in Hz")
    parser.add_argument("--seconds", type=positive_float, default=20.0, help="length of each run")
    parser.add_argument("--repeats", type=positive_int, default=2, help="runs of each variant")
    parser.add_argument("--view", action="store_true", help="also run with the live page")
    parser.add_argument(
        "--client",
        choices=("ws", "chromium", "none"),
        default="ws",
        help="--view: who watches the page (a websocket reader, headless Chromium, nobody)",
    )


def run(args: argparse.Namespace) -> list[dict[str, Any]]:
    from robot_retarget.errors import RetargetError
    from robot_retarget.motion.synthetic import demo_motion
    from robot_retarget.pipeline.defaults import default_model_name
    from robot_retarget.pipeline.step import RetargetStep
    from robot_retarget.robot.loader import load_robot_config
    from robot_retarget.runtime.loader import load_runtime_model

    if not (args.rate > 0 and args.seconds > 0 and args.repeats >= 1):
        raise RetargetError("--rate and --seconds must be positive, --repeats at least 1")
    if args.view:
        from robot_retarget.viewer.dependency import require_viser

        require_viser()
    config = load_robot_config(args.robot)
    motion = demo_motion(fps=30.0)
    step = RetargetStep(
        config,
        load_runtime_model(args.model or default_model_name()),
        motion.skeleton,
        rate_hz=args.rate,
    )
    step.retargeter.warm_up()
    variants = ["plain", "view"] if args.view else ["plain"]
    records = []
    for k in range(args.repeats):
        for variant in variants:
            records.append(_one_run(args, config, step, motion, variant == "view", k))
    return records


def _one_run(
    args: argparse.Namespace, config: Any, step: Any, motion: Any, view: bool, repeat: int
) -> dict[str, Any]:
    from robot_retarget.pipeline.live_mailbox import LiveFrame, Mailbox
    from robot_retarget.pipeline.loop import ControlLoop, LoopSettings
    from robot_retarget.sim.robot_bus import SimulatedRobotBus
    from robot_retarget.sources.replay import ReplaySource

    settings = LoopSettings(rate_hz=args.rate, duration_s=args.seconds, report_every_s=1e9)
    with SimulatedRobotBus(config, config.safe_pose) as sim:
        mailbox: Mailbox[LiveFrame] | None = None
        page = client = None
        profile: tempfile.TemporaryDirectory[str] | None = None
        if view:
            from robot_retarget.viewer.live_page import LivePage

            mailbox = Mailbox()
            page = LivePage(config, mailbox, measure=sim.present_q, port=0)
            if args.client != "none":
                profile = tempfile.TemporaryDirectory()
                client = _start_client(args.client, page.url, Path(profile.name))
                _wait_for_client(page, client)
        loop = ControlLoop(
            step,
            ReplaySource(motion, loop=True),
            sim.backend(),
            settings,
            mailbox=mailbox,
        )
        try:
            result = loop.run()
        finally:
            if client is not None:
                client.terminate()
                try:
                    client.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    client.kill()
                    client.wait()
            if page is not None:
                page.close()
            if profile is not None:
                profile.cleanup()
    s = result.stats
    label = f"view ({args.client})" if view else "plain"
    record: dict[str, Any] = {
        "variant": label,
        "run": repeat + 1,
        "rate_hz": args.rate,
        "ticks": s.ticks,
        "late_frames": s.late_frames,
        "held_ticks": s.late_ticks,
        "overruns": s.overruns,
        "jitter_median_ms": s.jitter_median_ms,
        "jitter_p99_ms": s.jitter_p99_ms,
        "latency_median_ms": s.latency_median_ms,
    }
    if page is not None:
        record["published"] = page.published
        record["publish_median_ms"] = float(np.median(page.publish_s)) * 1e3
        record["publish_p99_ms"] = float(np.percentile(page.publish_s, 99)) * 1e3
    return record


def _start_client(kind: str, url: str, profile: Path) -> subprocess.Popen[bytes]:
    from robot_retarget.errors import RetargetError

    if kind == "ws":
        cmd = [sys.executable, "-m", "robot_retarget.viewer.drain_client", url]
    else:
        from robot_retarget.viewer.chromium import HEADLESS_FLAGS, find_chromium

        exe = find_chromium()
        if exe is None:
            raise RetargetError("--client chromium: no chromium on the PATH (apt install chromium)")
        cmd = [exe, *HEADLESS_FLAGS, f"--user-data-dir={profile}", url]
    out = subprocess.PIPE if kind == "ws" else subprocess.DEVNULL
    return subprocess.Popen(cmd, stdout=out, stderr=subprocess.DEVNULL)


def _wait_for_client(page: Any, client: subprocess.Popen[bytes], timeout_s: float = 30.0) -> None:
    """Until the client is connected: the websocket reader says so on stdout; a browser
    counts once viser registers it (after its first camera message)."""
    from robot_retarget.errors import RetargetError

    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and client.poll() is None:
        if client.stdout is not None:
            ready, _, _ = select.select([client.stdout], [], [], 0.1)
            if ready and client.stdout.readline().strip() == b"connected":
                return
        elif page.server.get_clients():
            return
        else:
            time.sleep(0.05)
    raise RetargetError(
        f"the page's client did not connect within {timeout_s:g} s (exit code "
        f"{client.returncode}); try --client none"
    )

"""``stream --robot ROBOT --source SOURCE --backend sim|dynamixel``: drive a robot live.

SOURCE: ``replay:CLIP.bvh`` (real time; --loop, --speed), ``udp://127.0.0.1:9750`` (JSON or binary
frames, wire format in robot_retarget.sources.wire) or ``tcp-bvh://HOST:PORT`` (a BVH stream from
mocap software). Live sources use 127.0.0.1 unless --allow-remote; --token makes UDP senders prove
they know a shared secret. --allow-remote is refused without --token, unless --insecure-no-token
says that unauthenticated input is wanted (a tcp-bvh stream carries no token: it always needs
--insecure-no-token to reach another host). The control loop, watchdog and safety rules are in
robot_retarget.pipeline.loop; Ctrl-C (or SIGTERM) stops smoothly and switches the torque off. Live
statistics and source warnings go to stderr (statistics every --stats-every seconds and at exit).
--port: robot_retarget.cli.port_args (``PATH``, or ``BUS=PATH`` once per bus; a bus not named uses
the config's default_port). --record saves what was sent (after the safety layer, one row per
control tick) as a trajectory file; its path is checked before the robot moves
(robot_retarget.cli.output_paths), and if it cannot be written at the end the recording goes to a
fallback path that is printed. --view serves a live page (robot_retarget.viewer.live_page) fed
from the loop's one-slot mailbox by its own thread: the loop never waits for it.
"""

from __future__ import annotations

import argparse
import signal
import sys
from functools import partial
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any

from robot_retarget.cli.fallback_warning import fallback_warning
from robot_retarget.cli.foot_lock_arg import add_foot_lock_argument
from robot_retarget.cli.image_size_arg import image_size_argument
from robot_retarget.cli.port_args import add_port_argument, check_ports_exist
from robot_retarget.cli.tcp_port_arg import tcp_port_argument
from robot_retarget.number_args import positive_float
from robot_retarget.pipeline.defaults import MODEL_HELP
from robot_retarget.pipeline.input_filter import one_euro_argument

if TYPE_CHECKING:
    from collections.abc import Sequence

    from robot_retarget.pipeline.loop import LogEntry

NAME = "stream"
VIEW_PORT = 8080
VIEW_HOST = "127.0.0.1"
HELP = "Drive a robot (or the simulator) live from a replayed clip or a mocap stream."


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="op3", help="robot config name or YAML path")
    parser.add_argument(
        "--source",
        required=True,
        help="replay:CLIP.bvh | udp://127.0.0.1:9750 | tcp-bvh://127.0.0.1:PORT | "
        "udp-keypoints://127.0.0.1:9751 (COCO-17 2D keypoints, robot_retarget.sources.keypoints)",
    )
    parser.add_argument(
        "--keypoint-model",
        help="udp-keypoints: the 2D keypoint model's runtime .npz (default: the shipped causal "
        "agnostic2d; a model trained with centered=true looks ahead and cannot stream)",
    )
    parser.add_argument(
        "--no-image-planes",
        dest="image_planes",
        action="store_false",
        help="udp-keypoints: keep the keypoint model's answer as it is (by default each bone is "
        "turned into the plane the image puts it in, the camera fitted on the frames so far; "
        "see README 'Video input')",
    )
    parser.add_argument(
        "--image-size",
        type=image_size_argument,
        metavar="WxH",
        help="udp-keypoints: the camera image's width and height in pixels, e.g. 1280x720 (its "
        "centre is the camera's principal point for the image's planes; a packet's own "
        "image_size wins; without either the camera is assumed to point at the performer's mean "
        "hip position, which settles slowly when they walk about)",
    )
    parser.add_argument("--backend", choices=("sim", "dynamixel"), default="sim")
    add_port_argument(
        parser, "default: a bus not named opens its default_port from the robot config's buses"
    )
    parser.add_argument(
        "--rate", type=positive_float, help="control rate in Hz (default: the config's)"
    )
    parser.add_argument("--duration", type=positive_float, help="stop after S seconds")
    parser.add_argument(
        "--one-euro",
        type=one_euro_argument,
        metavar="MIN_HZ,BETA",
        help="smooth the input with a One-Euro filter (e.g. 2,0.3: 2 Hz cutoff when still, "
        "+0.3 Hz per rad/s): less servo chatter from a jittery pose estimator, some lag; off by "
        "default",
    )
    parser.add_argument(
        "--raw-positions",
        action="store_true",
        help="udp: solve position packets as sent; by default joints a tracker holds in place "
        "are carried with their parents, swapped left/right limbs are swapped back and "
        "frame-to-frame jitter is filtered as strongly as the stream shows it",
    )
    parser.add_argument("--model", help=MODEL_HELP)
    add_foot_lock_argument(parser)
    parser.add_argument("--loop", action="store_true", help="replay: start over at the end")
    parser.add_argument("--speed", type=positive_float, default=1.0, help="replay speed factor")
    parser.add_argument("--token", default="", help="shared secret UDP packets must carry")
    parser.add_argument(
        "--allow-remote",
        action="store_true",
        help="allow a non-loopback bind/connect address (needs --token, or --insecure-no-token)",
    )
    parser.add_argument(
        "--insecure-no-token",
        action="store_true",
        help="with --allow-remote: accept input from other hosts without a token (anyone who "
        "can reach the port can move the robot)",
    )
    parser.add_argument(
        "--stats-every",
        type=positive_float,
        default=5.0,
        help="print live statistics every S seconds",
    )
    parser.add_argument(
        "--record",
        type=Path,
        help="save the commands sent (after the safety layer) as OUT.npz|.csv|.json",
    )
    parser.add_argument("--force", action="store_true", help="replace an existing --record file")
    parser.add_argument(
        "--fix-registers",
        action="store_true",
        help="dynamixel: write the expected angle/position limits, Homing Offset and Drive Mode "
        "where another tool left other values, instead of refusing to connect",
    )
    parser.add_argument(
        "--view",
        action="store_true",
        help="serve a live page: commanded (and, with --backend sim, measured) angles, safety "
        "clips, watchdog state, latency (needs the [view] extra)",
    )
    parser.add_argument(
        "--view-port",
        type=tcp_port_argument,
        default=None,
        help=f"--view: port (default {VIEW_PORT}; the next free one if busy)",
    )
    parser.add_argument(
        "--view-host",
        default=None,
        help=f"--view: address to serve on (default {VIEW_HOST}; 0.0.0.0: watch from another "
        "machine, whose browser then does not compete with the loop for this one's CPU; the "
        "page is read-only)",
    )
    parser.add_argument("--no-browser", action="store_true", help="--view: do not open a browser")
    parser.add_argument(
        "--wake-on-input",
        action="store_true",
        help="live sources: retarget a frame as soon as it arrives instead of at the next tick "
        "(still within every joint's velocity limit over the shorter interval)",
    )


_SIGTERM_SEEN: list[bool] = []  # set by the handler: the stop is reported as SIGTERM's


def _on_sigterm(signum: int, frame: FrameType | None) -> None:
    _SIGTERM_SEEN.append(True)
    raise KeyboardInterrupt  # the loop's smooth stop handles both the same way


def run(args: argparse.Namespace) -> int:
    from robot_retarget.errors import RetargetError
    from robot_retarget.pipeline.backends import open_backend
    from robot_retarget.pipeline.defaults import default_model_name
    from robot_retarget.pipeline.loop import ControlLoop, LoopSettings, Mode
    from robot_retarget.pipeline.step import RetargetStep
    from robot_retarget.robot.loader import load_robot_config
    from robot_retarget.runtime.loader import load_runtime_model
    from robot_retarget.skeleton.canonical import default_canonical_skeleton
    from robot_retarget.sources import open_source
    from robot_retarget.sources.socket_source import SocketSource

    _check_source_options(args)
    _check_backend_options(args)
    _check_remote(args)
    if args.view:
        from robot_retarget.viewer.dependency import require_viser

        require_viser()  # before the robot moves: the install hint comes first
    if args.record is not None:
        _check_record(args)
    config = load_robot_config(args.robot)
    if args.rate is not None:
        from robot_retarget.hardware.safety import check_servo_rate

        # Before anything opens, and on the simulator too: it refuses what the servos would.
        check_servo_rate(config, args.rate)
    if args.backend == "dynamixel":
        from robot_retarget.pipeline.backends import parse_ports

        parse_ports(config, args.port)  # unknown bus names, a plain PATH on several buses
        check_ports_exist(args.port)
    elif args.port:
        raise RetargetError(
            f"--port names the servos' serial port, which only --backend dynamixel opens "
            f"(--backend {args.backend} opens none): drop --port, or stream to the servos with "
            "--backend dynamixel"
        )
    source = open_source(
        args.source,
        loop=args.loop,
        speed=args.speed,
        token=args.token,
        allow_remote=args.allow_remote,
        keypoint_model=args.keypoint_model,
        clean_positions=not args.raw_positions,
        image_planes=args.image_planes,
        image_size=args.image_size,
    )
    model = load_runtime_model(args.model or default_model_name())
    step = RetargetStep(  # refuses a foot lock the model lacks before it builds the solver
        config, model, default_canonical_skeleton(), rate_hz=args.rate, foot_lock=args.foot_lock
    )
    step.retargeter.warm_up()  # compile / page in before real time
    backend = open_backend(config, args.backend, args.port, fix_registers=args.fix_registers)

    def report(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    source.stats.on_warning = report  # e.g. every packet dropped as out of order

    settings = LoopSettings(
        rate_hz=args.rate,
        duration_s=args.duration,
        report_every_s=args.stats_every,
        wake_on_input=args.wake_on_input,
        input_filter=args.one_euro,
    )
    page = None
    mailbox = None
    if args.view:
        from robot_retarget.pipeline.live_mailbox import LiveFrame, Mailbox
        from robot_retarget.viewer.live_page import LivePage
        from robot_retarget.viewer.measurement import passive_measurement

        mailbox = Mailbox[LiveFrame]()
        page = LivePage(
            config,
            mailbox,
            measure=passive_measurement(backend),
            host=VIEW_HOST if args.view_host is None else args.view_host,
            port=VIEW_PORT if args.view_port is None else args.view_port,
        )
        report(f"live view: {page.url}")
        if not args.no_browser:
            import webbrowser

            webbrowser.open(page.url)
    loop = ControlLoop(
        step, source, backend, settings, report=report, record=bool(args.record), mailbox=mailbox
    )
    if isinstance(source, SocketSource):
        # Bound (or connected) before the robot is: a port in use or a server not there is
        # said before any servo is touched, and the banner names the port a port 0 got. The
        # loop's own start() then finds it open, and stops it whatever happens.
        try:
            source.start()
        except BaseException:
            if page is not None:
                page.close()
            raise
    rate = args.rate or config.control_rate_hz
    report(
        f"streaming {source.describe()} → {config.name} ({args.backend}) at {rate:g} Hz, "
        f"model {model.name}; Ctrl-C stops smoothly"
    )
    old: Any = None
    _SIGTERM_SEEN.clear()
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        old = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        result = loop.run()
    except BaseException:
        # The loop stopped on an error (torque is already off): keep what was recorded so far.
        if args.record is not None:
            _save_record(args.record, loop.log, config.joint_names, rate, force=args.force)
        raise
    finally:
        if old is not None:
            signal.signal(signal.SIGTERM, old)
        if page is not None:
            page.close()
    print(f"frames: {result.step.frames} retargeted, {result.stats.commands} commands sent")
    print(result.stats.line())
    overran = overrun_warning(  # ticks, not commands: a loop with no input sends none
        result.stats.overruns, result.stats.ticks, rate, rate_given=args.rate is not None
    )
    if overran is not None:
        print(overran, file=sys.stderr)
    print(loop.budget.report())
    print(source.stats.summary())
    for line in source.report_lines():
        print(line)
    print(loop.safety.report())
    print(f"solver fallbacks: {result.step.fallbacks}")
    warning = fallback_warning(result.step.fallbacks, result.step.frames)
    if warning is not None:
        print(warning)
    modes = ", ".join(f"{m.value}" for _, m in result.transitions)
    print(f"modes: {modes or 'none (no input arrived)'}")
    if result.stop_skipped:
        print(
            f"stopped by {'SIGTERM' if _SIGTERM_SEEN else 'Ctrl-C'} twice: the move to the safe "
            "pose was cut short, torque off where the robot stood (support it before you do "
            "this on a standing robot)"
        )
    elif result.interrupted:
        print(f"stopped by {'SIGTERM' if _SIGTERM_SEEN else 'Ctrl-C'}: torque off")
    if result.step.frames == 0 and not result.interrupted:
        received = source.stats.received
        why = (
            f"{received} packet(s) arrived and none was usable (the source line above says why)"
            if received
            else "is the sender running, and sending to this address and port?"
        )
        print(
            f"no input frame from {source.describe()}: nothing was retargeted or sent ({why})",
            file=sys.stderr,
        )
        if args.record is not None:
            print(f"nothing recorded: {args.record} not written", file=sys.stderr)
        return 1
    if not result.interrupted and not any(m is Mode.TRACKING for _, m in result.transitions):
        # Safe, but not what was asked for: say so rather than end as if the clip had played.
        print(
            "warning: the robot never tracked the motion: the stream ended (input over, or "
            "--duration) while the start ramp was still bringing the robot to it "
            f"({settings.ramp_speed_fraction:.0%} of the velocity limits from where the servos "
            "stood). Give a longer clip or --loop, or start the robot nearer the motion's "
            "first pose",
            file=sys.stderr,
        )
    if args.record is not None:
        _save_record(args.record, result.log, config.joint_names, rate, force=args.force)
    return 0


def _check_source_options(args: argparse.Namespace) -> None:
    """Options the chosen source would ignore are refused by name."""
    from robot_retarget.errors import RetargetError

    src = args.source
    for option, given, scheme, what in (
        ("--raw-positions", args.raw_positions, "udp://", "the position packets"),
        ("--no-image-planes", not args.image_planes, "udp-keypoints://", "the 2D keypoints"),
        ("--image-size", args.image_size is not None, "udp-keypoints://", "the camera"),
    ):
        if given and not src.startswith(scheme):
            raise RetargetError(
                f"{option} is about {what} of a {scheme} source, not {src!r}; leave it out"
            )
    ignored = []
    if not src.startswith("replay:"):
        ignored += [o for o, on in (("--loop", args.loop), ("--speed", args.speed != 1.0)) if on]
    elif args.wake_on_input:  # a replay has every frame at hand: there is nothing to wait for
        ignored.append("--wake-on-input")
    if args.keypoint_model is not None and not src.startswith("udp-keypoints://"):
        ignored.append("--keypoint-model")
    if not src.startswith(("udp://", "tcp-bvh://", "udp-keypoints://")):
        network = (("--token", bool(args.token)), ("--allow-remote", args.allow_remote),
                   ("--insecure-no-token", args.insecure_no_token))  # fmt: skip
        ignored += [o for o, on in network if on]
    elif args.insecure_no_token and not args.allow_remote:
        raise RetargetError(
            "--insecure-no-token is about accepting senders on other hosts, and without "
            "--allow-remote only this computer can send: drop it, or add --allow-remote"
        )
    if ignored:
        raise RetargetError(
            f"{', '.join(ignored)}: the source {src!r} does not use "
            f"{'it' if len(ignored) == 1 else 'them'}; leave "
            f"{'it' if len(ignored) == 1 else 'them'} out"
        )


def _check_backend_options(args: argparse.Namespace) -> None:
    """--fix-registers without the servos, and --view's options without --view, are refused
    by name."""
    from robot_retarget.errors import RetargetError

    if args.fix_registers and args.backend != "dynamixel":
        raise RetargetError(
            f"--fix-registers writes the servos' registers, and --backend {args.backend} opens "
            "no servos: drop it, or stream to the servos with --backend dynamixel"
        )
    unused = [
        option
        for option, given in (
            ("--view-port", args.view_port is not None),
            ("--view-host", args.view_host is not None),
            ("--no-browser", args.no_browser),
        )
        if given
    ]
    if unused and not args.view:
        raise RetargetError(
            f"{', '.join(unused)}: about the live page, which only --view serves; add --view "
            f"or leave {'it' if len(unused) == 1 else 'them'} out"
        )


def _check_remote(args: argparse.Namespace) -> None:
    """--allow-remote needs --token, or an explicit --insecure-no-token."""
    from robot_retarget.errors import SourceError

    if args.insecure_no_token and args.token:
        raise SourceError("--token and --insecure-no-token contradict each other; pass one")
    if args.token and args.source.startswith("tcp-bvh://"):
        raise SourceError(
            "--token works with udp:// sources only (a tcp-bvh stream carries no token); for "
            "a tcp-bvh server on another host pass --allow-remote --insecure-no-token"
        )
    network = args.source.startswith(("udp://", "tcp-bvh://", "udp-keypoints://"))
    if network and args.allow_remote and not args.token and not args.insecure_no_token:
        raise SourceError(
            "--allow-remote without --token would let anyone who can reach the port move the "
            "robot; pass --token SECRET (senders must send it), or --insecure-no-token to "
            "accept input without one"
        )


def _check_record(args: argparse.Namespace) -> None:
    """The --record path, before anything moves: suffix, folder exists and is writable, not
    an existing file without --force, not the replayed clip."""
    from robot_retarget.cli.output_paths import Output, check_outputs
    from robot_retarget.motion.trajectory import FORMATS

    inputs = [Path(args.source[len("replay:") :])] if args.source.startswith("replay:") else []
    check_outputs([Output("--record", args.record, FORMATS)], inputs=inputs, force=args.force)


OVERRUN_SHARE = 0.05  # of the loop's ticks: more overran, and the rate was not kept (a few
# overruns as a stream starts, e.g. while a tcp-bvh sender connects, are no such sign)


def overrun_warning(
    overruns: int, ticks_run: int, rate_hz: float, *, rate_given: bool
) -> str | None:
    """A warning when more than :data:`OVERRUN_SHARE` of the loop's ticks overran: the
    machine did not keep ``rate_hz`` (the servos got fewer, later commands than asked).
    ``rate_given``: the rate came from --rate (else it is the robot config's)."""
    ticks = overruns + ticks_run
    if ticks == 0 or overruns <= OVERRUN_SHARE * ticks:
        return None
    advice = (
        "use a lower --rate (the robot config's control rate is the default)"
        if rate_given
        else "this is the robot config's control rate: free the machine of other work"
    )
    return (
        f"warning: the control loop overran {overruns} of {ticks} ticks "
        f"({overruns / ticks:.0%}): this machine did not keep {rate_hz:g} Hz, so the servos "
        f"got fewer commands than asked; {advice}"
    )


def on_the_rate_grid(t_s: Any, q: Any, rate_hz: float) -> Any:
    """The commands (T, J) stamped ``t_s`` (T,) (the safety layer's timeline: each step within
    the velocity limit for the stamps' interval), as rows ``1 / rate_hz`` apart from the first,
    linearly between commands. A trajectory file has one rate: a row per command had played a
    stream with --wake-on-input's early ticks (297 rows of an 8 s stream at 20 Hz) or with
    missed ticks at the wrong speed. A row never steps faster than the commands did."""
    import numpy as np

    t = np.asarray(t_s, dtype=np.float64) - float(t_s[0])
    rows = np.asarray(q, dtype=np.float64)
    keep = np.append(np.diff(t) > 0.0, True)  # a repeated time: its last command
    t, rows = t[keep], rows[keep]
    grid = np.arange(int(np.floor(t[-1] * rate_hz + 1e-6)) + 1) / rate_hz
    return np.stack([np.interp(grid, t, rows[:, j]) for j in range(rows.shape[1])], axis=1)


def _save_record(
    path: Path,
    log: Sequence[LogEntry],
    joint_names: tuple[str, ...],
    rate_hz: float,
    *,
    force: bool,
) -> None:
    """Write the recording atomically; if its path fails now, to a fallback path (printed)."""
    if not log:
        print(f"nothing recorded (no command was sent): {path} not written")
        return
    import numpy as np

    from robot_retarget.cli.output_paths import save_with_fallback
    from robot_retarget.motion.trajectory import RobotTrajectory

    stamps = np.array([e.stamp_s for e in log])
    q = on_the_rate_grid(stamps, np.array([e.q for e in log]), rate_hz)
    traj = RobotTrajectory(joint_names, q, rate_hz)

    def warn(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    written = save_with_fallback(
        path, partial(traj.write, overwrite=True), force=force, option="--record", warn=warn
    )
    print(f"recorded {len(log)} commands to {written} ({len(q)} rows at {rate_hz:g} Hz)")

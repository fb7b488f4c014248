"""``convert INPUT --robot ROBOT --out OUT``: human clip(s) → robot trajectory file(s).

INPUT is a BVH file or a folder (every .bvh inside is converted, the folder structure kept
under OUT), or 2D keypoints from a camera pose estimator (an OpenPose JSON folder, a MediaPipe
landmark .json, COCO-17 .jsonl: robot_retarget.sources.keypoints), lifted to 3D rotations by
the keypoint model (robot_retarget.keypoints.lift) and converted as one clip.
Each frame goes through the live path's step (network → optimizer → safety), see
robot_retarget.pipeline.convert. Every output path is checked before any work starts
(robot_retarget.cli.output_paths): an output is never an input (not even with --force), no two
outputs share a path, existing outputs are kept unless --force, a file's folder must exist and
be writable (folder outputs are created). A clip's outputs are written atomically, all or none.
A clip that fails is reported and the others still convert; the exit code is 1 when any clip
failed.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import TextIO

from robot_retarget.errors import MotionFormatError, RetargetError

NAME = "convert"
HELP = "Retarget BVH clip(s) to a robot trajectory (.npz/.csv/.json), preview, robot BVH."

_FORMATS = (".npz", ".csv", ".json")


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", type=Path, help="BVH file, or a folder of BVH files")
    parser.add_argument("--robot", default="op3", help="robot config name or YAML path")
    parser.add_argument(
        "--out", type=Path, required=True, help="OUT.npz|.csv|.json (a folder for folder input)"
    )
    parser.add_argument(
        "--format",
        choices=[f[1:] for f in _FORMATS],
        default="npz",
        help="file format for folder input (default npz)",
    )
    parser.add_argument("--model", help="model name or checkpoint path (default: the default)")
    parser.add_argument(
        "--fps", type=float, help="output frame rate (default: the robot's control rate)"
    )
    parser.add_argument("--preview", type=Path, help="OUT.gif|.mp4 (a folder for folder input)")
    parser.add_argument(
        "--bvh-out", type=Path, help="robot motion as BVH (a folder for folder input)"
    )
    parser.add_argument("--max-frames", type=int, help="convert only the first N frames")
    parser.add_argument(
        "--keypoint-model", help="2D keypoint input: the keypoint model's .npz (default: shipped)"
    )
    parser.add_argument(
        "--keypoint-fps",
        type=float,
        help="2D keypoint input: the camera's frame rate (default: the file's, else 30)",
    )
    parser.add_argument("--force", action="store_true", help="replace existing outputs")
    parser.add_argument(
        "--lead-in",
        action="store_true",
        help="prepend the move from the robot's init pose to the first frame at 25 %% of the "
        "velocity limits (the stream's ramp speed), stamped before t = 0 (t0 < 0)",
    )


@dataclass(frozen=True)
class ClipReport:
    clip: Path
    out: Path
    frames: int = 0
    wall_s: float = 0.0
    limits_ok: bool = False
    clipped_commands: int = 0
    clipped_joints: int = 0
    fallbacks: int = 0
    error: str | None = None


class ProgressBar:
    """A one-line text progress bar on stderr, redrawn in place on a terminal (at most ~50
    times per task); only the final line when stderr is a file."""

    def __init__(self, label: str, *, width: int = 30, stream: TextIO | None = None) -> None:
        self.label = label
        self.width = width
        self.stream = stream if stream is not None else sys.stderr
        self._last = -1
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())

    def __call__(self, done: int, total: int) -> None:
        step = max(1, total // 50)
        if done != total and (done - self._last < step or not self._tty):
            return  # not a terminal (a log file): only the final line
        self._last = done
        filled = self.width * done // max(total, 1)
        bar = "#" * filled + "-" * (self.width - filled)
        pct = 100 * done // max(total, 1)
        end = "\n" if done >= total else ""
        prefix = "\r" if self._tty else ""
        self.stream.write(f"{prefix}{self.label} [{bar}] {pct:3d}% ({done}/{total}){end}")
        self.stream.flush()


def _extra_path(base: Path | None, clip: Path, root: Path, suffix: str) -> Path | None:
    if base is None:
        return None
    if root.is_dir() and clip != root:  # a keypoint folder is one clip
        return base / clip.relative_to(root).with_suffix(suffix)
    return base


@dataclass(frozen=True)
class _Job:
    clip: Path
    out: Path
    preview: Path | None
    bvh_out: Path | None


def _plan(args: argparse.Namespace) -> list[_Job]:
    """Every clip with its outputs, all checked before any work (robot_retarget.cli.
    output_paths): suffixes, no output on an input or on another output, no overwrite
    without --force, writable folders (folder outputs are created when missing)."""
    from robot_retarget.cli.output_paths import Output, check_folder, check_outputs
    from robot_retarget.pipeline.convert import output_paths
    from robot_retarget.render.preview import FORMATS as PREVIEW_FORMATS
    from robot_retarget.render.preview import check_preview_path
    from robot_retarget.sources.keypoints import is_keypoint_input

    src: Path = args.input
    if not src.exists():
        raise MotionFormatError("no such file or folder", path=src)
    keypoints = is_keypoint_input(src)
    folder = src.is_dir() and not keypoints
    suffix = "." + args.format if folder else args.out.suffix.lower()
    pairs = [(src, args.out)] if keypoints else output_paths(src, args.out, suffix)
    if not pairs:
        raise MotionFormatError("no .bvh files in this folder", path=src)
    jobs = [
        _Job(
            clip,
            out,
            _extra_path(args.preview, clip, src, ".gif"),
            _extra_path(args.bvh_out, clip, src, ".bvh"),
        )
        for clip, out in pairs
    ]
    if folder:
        for option, base in (("--out", args.out), ("--preview", args.preview),
                             ("--bvh-out", args.bvh_out)):  # fmt: skip
            if base is not None:
                check_folder(base, option=option, create=True)
    outputs: list[Output] = []
    for job in jobs:
        outputs.append(Output("--out", job.out, _FORMATS, make_folders=folder))
        if job.preview is not None:
            outputs.append(Output("--preview", job.preview, PREVIEW_FORMATS, folder))
        if job.bvh_out is not None:
            outputs.append(Output("--bvh-out", job.bvh_out, (".bvh",), folder))
    check_outputs(outputs, inputs=[job.clip for job in jobs], force=args.force)
    if jobs[0].preview is not None:
        check_preview_path(jobs[0].preview, overwrite=True)  # MP4 needs ffmpeg
    return jobs


def run(args: argparse.Namespace) -> int:
    from robot_retarget.cli.output_paths import StagedWrites
    from robot_retarget.keypoints.lift import load_keypoint_motion
    from robot_retarget.motion.human_motion import load_motion
    from robot_retarget.pipeline.convert import convert_motion
    from robot_retarget.pipeline.defaults import default_model_name
    from robot_retarget.pipeline.robot_bvh import write_robot_bvh
    from robot_retarget.pipeline.step import RetargetStep
    from robot_retarget.render.preview import render_preview
    from robot_retarget.robot.loader import load_robot_config
    from robot_retarget.runtime.loader import load_runtime_model
    from robot_retarget.skeleton.canonical import default_canonical_skeleton
    from robot_retarget.sources.keypoints import is_keypoint_input

    if args.fps is not None and not args.fps > 0:
        raise RetargetError(f"--fps must be positive, got {args.fps}")
    jobs = _plan(args)
    folder = args.input.is_dir() and not is_keypoint_input(args.input)
    config = load_robot_config(args.robot)
    model = load_runtime_model(args.model or default_model_name())
    print(f"robot {config.name}, model {model.name}, {len(jobs)} clip(s)", file=sys.stderr)
    step = RetargetStep(config, model, default_canonical_skeleton())
    reports: list[ClipReport] = []
    t_all = time.perf_counter()
    for k, job in enumerate(jobs):
        clip, out = job.clip, job.out
        try:
            if is_keypoint_input(clip):
                lifted = load_keypoint_motion(
                    clip,
                    model=args.keypoint_model,
                    fps=args.keypoint_fps,
                    max_frames=args.max_frames,
                )
                motion = lifted.motion
                print(
                    f"{clip}: {motion.num_frames} keypoint frames at {motion.fps:g} fps, "
                    f"{lifted.missing_fraction:.1%} of points missing, {lifted.frames_held} "
                    "frame(s) without a body (the last seen pose held)",
                    file=sys.stderr,
                )
            else:
                motion = load_motion(clip, max_frames=args.max_frames)
            label = f"[{k + 1}/{len(jobs)}] {clip.name}"
            result = convert_motion(
                motion,
                step,
                fps=args.fps,
                progress=ProgressBar(label),
                lead_in_speed_fraction=0.25 if args.lead_in else None,
            )
            traj = result.trajectory
            # All of a clip's outputs, or none: each is written to a temporary file next to
            # it and moved into place only when every one of them has been written.
            with StagedWrites(force=args.force) as stage:
                stage.write(
                    out, partial(traj.write, overwrite=True), option="--out", make_folders=folder
                )
                if job.bvh_out is not None:
                    stage.write(
                        job.bvh_out,
                        partial(write_robot_bvh, config=config, trajectory=traj, overwrite=True),
                        option="--bvh-out",
                        make_folders=folder,
                    )
                if job.preview is not None:
                    stage.write(
                        job.preview,
                        partial(
                            render_preview,
                            human_positions=motion.positions(),
                            human_fps=motion.fps,
                            config=config,
                            robot_q=traj.q,
                            robot_fps=traj.fps,
                            title=f"{clip.name} → {config.name} ({model.name})",
                            overwrite=True,
                        ),
                        option="--preview",
                        make_folders=folder,
                    )
            reports.append(
                ClipReport(
                    clip,
                    out,
                    result.frames,
                    result.wall_s,
                    result.limits.ok,
                    result.safety_commands_clipped,
                    result.safety_joint_clips,
                    result.fallbacks,
                )
            )
        except (RetargetError, OSError, ValueError) as exc:
            print(f"error: {clip}: {exc}", file=sys.stderr)
            reports.append(ClipReport(clip, out, error=str(exc)))
    print(format_summary(reports, time.perf_counter() - t_all))
    return 1 if any(r.error for r in reports) else 0


def format_summary(reports: list[ClipReport], total_wall_s: float) -> str:
    ok = [r for r in reports if r.error is None]
    frames = sum(r.frames for r in ok)
    compute = sum(r.wall_s for r in ok)
    lines = ["", "summary:"]
    for r in reports:
        if r.error is not None:
            lines.append(f"  FAILED {r.clip}: {r.error}")
        else:
            lines.append(
                f"  {r.out}: {r.frames} frames, {r.wall_s:.2f} s "
                f"({r.frames / max(r.wall_s, 1e-9):.0f} frames/s), limits "
                f"{'respected' if r.limits_ok else 'VIOLATED'}, safety clipped "
                f"{r.clipped_commands} commands ({r.clipped_joints} joint values), "
                f"{r.fallbacks} solver fallbacks"
            )
    lines.append(
        f"  total: {len(ok)} of {len(reports)} clips, {frames} frames, wall time "
        f"{total_wall_s:.2f} s, {frames / max(compute, 1e-9):.0f} frames/s, limits "
        f"{'respected' if all(r.limits_ok for r in ok) else 'VIOLATED'}, safety clipped "
        f"{sum(r.clipped_commands for r in ok)} commands, "
        f"{sum(r.fallbacks for r in ok)} solver fallbacks"
    )
    return "\n".join(lines)

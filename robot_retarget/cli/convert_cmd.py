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

``--workers N`` (folder input) converts the clips on N workers, on Ray for N > 1 (the
``[scale]`` extra; ``--ray-address`` joins an existing cluster), with a manifest in the output
folder that makes a re-run skip the clips already done and retry the ones that failed
(robot_retarget.pipeline.batch_convert, clip_pool, manifest). Every clip goes through the same
:class:`~robot_retarget.pipeline.clip_converter.ClipConverter` either way, so the files are the
same bit for bit (all but ``frame_ms``, the measured compute time per frame).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import TextIO

from robot_retarget.cli.fallback_warning import fallback_warning
from robot_retarget.cli.foot_lock_arg import add_foot_lock_argument
from robot_retarget.errors import MotionFormatError, RetargetError
from robot_retarget.motion.frame_rate import FPS_RANGE, plausible_fps
from robot_retarget.pipeline.clip_converter import (
    ClipConverter,
    ClipJob,
    ClipReport,
    ConvertOptions,
)
from robot_retarget.pipeline.defaults import MODEL_HELP

NAME = "convert"
HELP = "Retarget BVH clip(s) to a robot trajectory (.npz/.csv/.json), preview, robot BVH."

_FORMATS = (".npz", ".csv", ".json")


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "input",
        type=Path,
        help="a BVH file, a folder of BVH files, or 2D keypoints (an OpenPose JSON folder, a "
        "MediaPipe .json, COCO-17 .jsonl)",
    )
    parser.add_argument("--robot", default="op3", help="robot config name or YAML path")
    parser.add_argument(
        "--out", type=Path, required=True, help="OUT.npz|.csv|.json (a folder for folder input)"
    )
    parser.add_argument(
        "--format",
        choices=[f[1:] for f in _FORMATS],
        help="file format for folder input (default npz; a single clip's is --out's suffix)",
    )
    parser.add_argument("--model", help=MODEL_HELP)
    parser.add_argument(
        "--fps", type=float, help="output frame rate (default: the robot's control rate)"
    )
    parser.add_argument("--preview", type=Path, help="OUT.gif|.mp4 (a folder for folder input)")
    parser.add_argument(
        "--bvh-out", type=Path, help="robot motion as BVH (a folder for folder input)"
    )
    parser.add_argument("--max-frames", type=int, help="convert only the first N frames")
    parser.add_argument(
        "--keypoint-model",
        help="2D keypoint input: the keypoint model, a runtime .npz or a shipped name "
        "(default: agnostic2d_clip, which sees a second ahead of each frame; agnostic2d: the "
        "causal one stream runs)",
    )
    parser.add_argument(
        "--keypoint-fps",
        type=float,
        help="2D keypoint input: the camera's frame rate (default: the file's, else 30)",
    )
    parser.add_argument(
        "--no-image-planes",
        dest="image_planes",
        action="store_false",
        help="2D keypoint input: keep the keypoint model's 3D answer as it is (by default each "
        "bone is turned into the plane the image puts it in, see README 'Video input')",
    )
    parser.add_argument(
        "--canonical-input",
        action="store_true",
        help="a skeleton-aware model (san) reads BVH clips on their own skeleton when it has an "
        "encoder for it; this feeds it the canonical joints instead, as stream does",
    )
    add_foot_lock_argument(parser)
    parser.add_argument(
        "--stream-branches",
        action="store_true",
        help="settle each limb in the first frame's best branch and leave the swing feet as "
        "solved, as stream does (the file then matches a stream of the clip at the same "
        "rate); default: each limb's branch chosen on the whole clip, the swing feet lifted "
        "to the performer's height, the feet held in double support",
    )
    parser.add_argument(
        "--feet-as-solved",
        action="store_true",
        help="leave the feet as solved: no swing foot lifted to the performer's height by its "
        "ankle's pitch joint, no foot held against the other in double support by its leg "
        "(--stream-branches implies it)",
    )
    parser.add_argument("--force", action="store_true", help="replace existing outputs")
    parser.add_argument(
        "--lead-in",
        action="store_true",
        help="prepend the move from the robot's init pose to the first frame at 25 %% of the "
        "velocity limits (the stream's ramp speed), stamped before t = 0 (t0 < 0)",
    )
    parser.add_argument(
        "--workers",
        type=int,
        help="folder input: convert clips on N workers (Ray, the [scale] extra, for N > 1) with "
        "a manifest in the output folder: a re-run skips clips already done, retries failed ones",
    )
    parser.add_argument(
        "--ray-address",
        help="folder input: run the clips on an existing Ray cluster (HOST:6379, ray://HOST:10001 "
        "or auto); without --workers, one worker per CPU of the cluster",
    )


class ProgressBar:
    """A one-line text progress bar on stderr, redrawn in place on a terminal (at most ~50
    times per task); only the final line when stderr is a file. ``unit``: what the count
    counts, shown after it."""

    def __init__(
        self, label: str, *, width: int = 30, stream: TextIO | None = None, unit: str = ""
    ) -> None:
        self.label = label
        self.unit = f" {unit}" if unit else ""
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
        self.stream.write(
            f"{prefix}{self.label} [{bar}] {pct:3d}% ({done}/{total}{self.unit}){end}"
        )
        self.stream.flush()


def _extra_path(base: Path | None, clip: Path, root: Path, suffix: str) -> Path | None:
    if base is None:
        return None
    if root.is_dir() and clip != root:  # a keypoint folder is one clip
        return base / clip.relative_to(root).with_suffix(suffix)
    return base


def _note_keypoints_left(src: Path) -> None:
    """Say so when a folder of clips also holds keypoint input, which a folder's conversion
    does not take (it converted the .bvh clips and passed the rest over without a word)."""
    kinds = (".json", ".jsonl")
    left = sorted(p for p in src.rglob("*") if p.is_file() and p.suffix.lower() in kinds)
    if left:
        names = ", ".join(str(p.relative_to(src)) for p in left[:3])
        more = f" and {len(left) - 3} more" if len(left) > 3 else ""
        print(
            f"note: {len(left)} .json/.jsonl file(s) under {src} are not converted ({names}"
            f"{more}): a folder's conversion takes its .bvh clips; convert 2D keypoint input "
            "one file or one OpenPose folder at a time",
            file=sys.stderr,
        )


def _plan(
    args: argparse.Namespace, replaceable: Callable[[Path], bool] | None = None
) -> list[ClipJob]:
    """Every clip with its outputs, all checked before any work (robot_retarget.cli.
    output_paths): suffixes, no output on an input or on another output, no overwrite
    without --force, writable folders (folder outputs are created when missing).
    ``replaceable(clip)``: the clip's existing outputs may be replaced without --force (they
    belong to an earlier run of the same job, as its manifest says)."""
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
    _check_options_fit_input(args, src, keypoints=keypoints, folder=folder)
    suffix = "." + (args.format or "npz") if folder else args.out.suffix.lower()
    pairs = [(src, args.out)] if keypoints else output_paths(src, args.out, suffix)
    if not pairs:
        raise MotionFormatError("no .bvh files in this folder", path=src)
    if folder:
        _note_keypoints_left(src)
    owned = replaceable or (lambda _clip: False)
    jobs = [
        ClipJob(
            clip,
            out,
            _extra_path(args.preview, clip, src, ".gif"),
            _extra_path(args.bvh_out, clip, src, ".bvh"),
            force=args.force or owned(clip),
            make_folders=folder,
        )
        for clip, out in pairs
    ]
    if folder:
        for option, base in (("--out", args.out), ("--preview", args.preview),
                             ("--bvh-out", args.bvh_out)):  # fmt: skip
            if base is not None:
                check_folder(base, option=option, create=True)
    outputs: list[Output] = []
    theirs: list[Output] = []  # outputs no earlier run of this job made
    for job in jobs:
        mine = [Output("--out", job.out, _FORMATS, make_folders=folder)]
        if job.preview is not None:
            mine.append(Output("--preview", job.preview, PREVIEW_FORMATS, folder))
        if job.bvh_out is not None:
            mine.append(Output("--bvh-out", job.bvh_out, (".bvh",), folder))
        outputs += mine
        if not owned(job.clip):
            theirs += mine
    inputs = [job.clip for job in jobs]
    if len(theirs) == len(outputs):
        check_outputs(outputs, inputs=inputs, force=args.force)
    else:
        check_outputs(outputs, inputs=inputs, force=True)
        check_outputs(theirs, inputs=inputs, force=args.force)
    if jobs[0].preview is not None:
        check_preview_path(jobs[0].preview, overwrite=True)  # MP4 needs ffmpeg
    return jobs


def _check_options_fit_input(
    args: argparse.Namespace, src: Path, *, keypoints: bool, folder: bool
) -> None:
    """Options that the input would ignore are refused by name, before any work."""
    if not keypoints:
        given = [
            option
            for option, used in (
                ("--keypoint-model", args.keypoint_model is not None),
                ("--keypoint-fps", args.keypoint_fps is not None),
                ("--no-image-planes", not args.image_planes),
            )
            if used
        ]
        if given:
            raise RetargetError(
                f"{', '.join(given)}: for 2D keypoint input, and {src} is BVH motion: drop "
                f"{'it' if len(given) == 1 else 'them'}"
            )
    elif args.canonical_input:
        raise RetargetError(
            f"--canonical-input: for BVH input read by a skeleton-aware model, and {src} is 2D "
            "keypoints (lifted onto the canonical joints already): drop it"
        )
    elif args.keypoint_model is not None:
        from robot_retarget.runtime.agnostic2d import keypoint_model_path

        keypoint_model_path(args.keypoint_model)  # a typo is one error, not one per clip
    if folder and args.out.suffix.lower() in _FORMATS:
        raise RetargetError(
            f"--out {args.out}: a folder of clips is written to a folder of files, not to one "
            f"{args.out.suffix} file; name a folder (--format picks the files' format)"
        )
    if not folder and args.format is not None and "." + args.format != args.out.suffix.lower():
        raise RetargetError(
            f"--format {args.format}: for folder input; one clip is written in --out's format "
            f"({args.out.suffix or 'no suffix'}): name --out …{'.' + args.format} instead"
        )


def _options(args: argparse.Namespace) -> ConvertOptions:
    from robot_retarget.pipeline.defaults import default_model_name

    return ConvertOptions(
        robot=args.robot,
        model=args.model or default_model_name(),
        fps=args.fps,
        max_frames=args.max_frames,
        lead_in=args.lead_in,
        keypoint_model=args.keypoint_model,
        keypoint_fps=args.keypoint_fps,
        keypoint_image_planes=args.image_planes,
        canonical_input=args.canonical_input,
        foot_lock=args.foot_lock,
        whole_clip_branches=not args.stream_branches,
        lift_swing_feet=not (args.stream_branches or args.feet_as_solved),
        hold_double_support=not (args.stream_branches or args.feet_as_solved),
    )


def _solves_note(options: ConvertOptions, control_rate_hz: float) -> str:
    """What a clip's progress bar counts: solves of the clip's frames resampled to the output
    rate, one pass per start of the branch choice and one that writes the file
    (robot_retarget.pipeline.convert): 96 frames at 125 Hz count to 384."""
    from robot_retarget.pipeline.limb_branch_choice import STARTS

    rate = options.fps if options.fps is not None else control_rate_hz
    if not options.whole_clip_branches:
        return f"progress counts solves, one per frame at {rate:g} Hz"
    return (
        f"progress counts solves, {STARTS + 1} per frame at {rate:g} Hz ({STARTS} passes choose "
        "each limb's branch, 1 writes the file)"
    )


def run(args: argparse.Namespace) -> int:
    for option, value in (("--fps", args.fps), ("--keypoint-fps", args.keypoint_fps)):
        if value is not None and not plausible_fps(value):
            raise RetargetError(f"{option} must be a frame rate, {FPS_RANGE}, got {value:g}")
    if args.max_frames is not None and args.max_frames < 1:
        raise RetargetError(f"--max-frames must be at least 1, got {args.max_frames}")
    if args.workers is not None or args.ray_address is not None:
        return _run_batch(args)
    jobs = _plan(args)
    options = _options(args)
    converter = ClipConverter(options)
    print(
        f"robot {converter.config.name}, model {converter.model.name}, {len(jobs)} clip(s); "
        + _solves_note(options, converter.config.control_rate_hz),
        file=sys.stderr,
    )
    reports: list[ClipReport] = []
    t_all = time.perf_counter()
    for k, job in enumerate(jobs):
        report = converter.convert(
            job,
            ProgressBar(f"[{k + 1}/{len(jobs)}] {job.clip.name}", unit="solves"),
            log=partial(print, file=sys.stderr),
        )
        if report.error is not None:
            print(f"error: {clip_error(report)}", file=sys.stderr)
        reports.append(report)
    summary = format_summary(reports, time.perf_counter() - t_all)
    if summary:
        print(summary)
    return 1 if any(r.error for r in reports) else 0


def _run_batch(args: argparse.Namespace) -> int:
    """A folder on a pool of workers (Ray for more than one, or for --ray-address), with a
    manifest in the output folder: a re-run skips what is done and retries what failed."""
    from robot_retarget.pipeline.batch_convert import clip_key, plan_batch, run_batch
    from robot_retarget.pipeline.clip_pool import LocalClipPool, RayClipPool, import_ray
    from robot_retarget.pipeline.manifest import Manifest
    from robot_retarget.robot.loader import load_robot_config
    from robot_retarget.runtime.loader import check_foot_lock, load_runtime_model
    from robot_retarget.sources.keypoints import is_keypoint_input

    workers: int | None = args.workers
    if workers is not None and workers < 1:
        raise RetargetError(f"--workers must be at least 1, got {workers}")
    on_ray = (workers or 1) > 1 or args.ray_address is not None
    if on_ray:
        import_ray(workers or 0)  # before any work: says how to install the [scale] extra
    src: Path = args.input
    if not src.is_dir() or is_keypoint_input(src):
        raise RetargetError(
            f"--workers and --ray-address convert a folder of BVH clips; {src} is not one: "
            "run without them"
        )
    options = _options(args)
    load_robot_config(options.robot)  # a wrong name fails here, once, not in every worker
    check_foot_lock(load_runtime_model(options.model), foot_lock=options.foot_lock)
    settings = {
        "robot": options.robot,
        "model": options.model,
        "fps": options.fps,
        "max_frames": options.max_frames,
        "lead_in": options.lead_in,
        "foot_lock": options.foot_lock,
        "whole_clip_branches": options.whole_clip_branches,
        "lift_swing_feet": options.lift_swing_feet,
        "hold_double_support": options.hold_double_support,
        "format": args.format or "npz",
    }
    manifest = Manifest.open(args.out, settings, fresh=args.force)
    jobs = _plan(args, lambda clip: manifest.owns(clip_key(clip, src)))
    plan = plan_batch(jobs, src, manifest)
    where = f"Ray at {args.ray_address}" if args.ray_address else f"{workers or 1} worker(s)"
    print(
        f"robot {options.robot}, model {options.model}, {len(jobs)} clip(s): "
        f"{len(plan.skipped)} already done (manifest {manifest.path}), "
        f"{len(plan.todo)} to convert on {where}",
        file=sys.stderr,
    )
    bar = ProgressBar(f"convert on {where}")
    done = 0

    def report(r: ClipReport) -> None:
        nonlocal done
        done += 1
        if r.error is not None:
            print(f"error: {clip_error(r)}", file=sys.stderr)
        bar(done, len(plan.todo))

    if not plan.todo:
        print("nothing to convert: every clip is done (--force converts them all again)")
        return 0
    pool = RayClipPool(options, workers, args.ray_address) if on_ray else LocalClipPool(options)
    with pool:
        print(f"workers ready in {pool.startup_s:.1f} s", file=sys.stderr)
        t_all = time.perf_counter()
        reports = run_batch(plan, manifest, pool, report)
    order = {job.clip: k for k, job in enumerate(plan.todo)}
    reports.sort(key=lambda r: order[r.clip])
    summary = format_summary(reports, time.perf_counter() - t_all)
    if summary:
        print(summary)
    return 1 if any(r.error for r in reports) else 0


def clip_error(report: ClipReport) -> str:
    """A failed clip's error, led by the clip's path once (most errors already name it)."""
    error = str(report.error)
    clip = str(report.clip)
    return error if error.startswith((f"{clip}:", f"{clip},")) else f"{clip}: {error}"


def format_summary(reports: list[ClipReport], total_wall_s: float) -> str:
    # Here, not at the top: it loads the optimizer, and `convert --help` needs none.
    from robot_retarget.pipeline.convert import clip_line, counted, lead_in_part

    ok = [r for r in reports if r.error is None]
    frames = sum(r.frames for r in ok)
    solved = sum(r.solved_frames for r in ok)  # the rate leaves out --lead-in's frames
    compute = sum(r.wall_s for r in ok)
    if len(reports) == 1 and reports[0].error is not None:
        return ""  # one clip, failed: its error line above says it all
    lines = ["", "summary:"]
    for r in reports:
        if r.error is not None:
            lines.append(f"  FAILED {clip_error(r)}")
        else:
            lines.append(
                f"  {r.out}: "
                + clip_line(r.frames, r.lead_in_frames, r.wall_s, r.limits_ok,
                            r.clipped_commands, r.clipped_joints, r.fallbacks)
            )  # fmt: skip
    if not ok:
        lines.append(f"  total: 0 of {len(reports)} clips converted")
        return "\n".join(lines)
    lines.append(
        f"  total: {len(ok)} of {len(reports)} clips, {counted(frames, 'frame')}"
        f"{lead_in_part(frames - solved)}, wall time "
        f"{total_wall_s:.2f} s, {solved / max(compute, 1e-9):.0f} frames/s, limits "
        f"{'respected' if all(r.limits_ok for r in ok) else 'VIOLATED'}, safety clipped "
        f"{counted(sum(r.clipped_commands for r in ok), 'command')}, "
        f"{counted(sum(r.fallbacks for r in ok), 'solver fallback')}"
    )
    warning = fallback_warning(sum(r.fallbacks for r in ok), solved)
    if warning is not None:
        lines.append(f"  {warning}")
    return "\n".join(lines)

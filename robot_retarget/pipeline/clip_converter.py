"""One clip → its output files: what ``convert`` does per clip, in one process or a Ray worker.

A :class:`ClipConverter` holds one robot config, one model and one :class:`RetargetStep` (its
JIT-compiled solver built, or loaded from the disk cache, once) and converts clip after clip
with it; a clip's result does not depend on the clips converted before it (the step is reset
per clip), so any split of a folder over workers gives the same files. A clip's outputs are
written atomically, all or none (robot_retarget.cli.output_paths.StagedWrites); a clip that
cannot be read or converted comes back as a :class:`ClipReport` with its error, never raised.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

from robot_retarget.errors import ModelLoadError, RetargetError

if TYPE_CHECKING:
    from robot_retarget.keypoints.camera_fit import CameraEstimate
    from robot_retarget.motion.bvh import BvhClip
    from robot_retarget.motion.human_motion import HumanMotion
    from robot_retarget.nn.models.san import SAN
    from robot_retarget.pipeline.precomputed_step import PrecomputedStep

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class ConvertOptions:
    """The per-clip settings of a ``convert`` run (the same for every clip of a job)."""

    robot: str
    model: str
    fps: float | None = None
    max_frames: int | None = None
    lead_in: bool = False
    keypoint_model: str | None = None
    keypoint_fps: float | None = None
    # 2D keypoint input: bones turned into the planes the image puts them in
    # (robot_retarget.keypoints.reprojection).
    keypoint_image_planes: bool = True
    # A skeleton-aware model (san) reads a BVH clip on its own skeleton when it has an encoder
    # for it; True feeds it the canonical joints instead, as ``stream`` does.
    canonical_input: bool = False
    # The residual network's foot lock (off on the robot by default: RetargetStep).
    foot_lock: bool = False
    # Each limb's branch chosen on the whole clip (robot_retarget.pipeline.limb_branch_choice);
    # False: the first frame's best, as ``stream`` runs it.
    whole_clip_branches: bool = True
    # Swing feet lifted to the performer's height (robot_retarget.pipeline.swing_clearance);
    # False: as solved, as ``stream`` sends them.
    lift_swing_feet: bool = True
    # Feet in double support held against each other (robot_retarget.pipeline.double_support);
    # False: as solved, as ``stream`` sends them.
    hold_double_support: bool = True


@dataclass(frozen=True)
class ClipJob:
    """A clip and its outputs. ``force``: an existing output may be replaced;
    ``make_folders``: its outputs lie under a folder output whose subfolders may be created."""

    clip: Path
    out: Path
    preview: Path | None = None
    bvh_out: Path | None = None
    force: bool = False
    make_folders: bool = False

    def outputs(self) -> list[Path]:
        return [p for p in (self.out, self.bvh_out, self.preview) if p is not None]


def _camera_summary(camera: CameraEstimate | None, image_planes: bool) -> str:
    """What the image's planes assumed of the camera, for convert's log line."""
    if not image_planes:
        return "image planes off (--no-image-planes)"
    if camera is None:
        return "image planes skipped: the keypoints could not tell a camera"
    return (
        f"bones turned into the image's planes, camera estimated at "
        f"{math.degrees(camera.elevation_rad):.0f}° elevation, focal {camera.focal_px:.0f} px"
    )


@dataclass(frozen=True)
class ClipReport:
    """What became of one clip: its frame count, compute time and fidelity figures (limits
    respected, safety-layer clips, solver fallbacks), or the error that stopped it."""

    clip: Path
    out: Path
    frames: int = 0
    wall_s: float = 0.0
    limits_ok: bool = False
    clipped_commands: int = 0
    clipped_joints: int = 0
    fallbacks: int = 0
    error: str | None = None
    position_excess_rad: float = 0.0
    velocity_excess_rad: float = 0.0
    cpu_s: float = 0.0  # the converting process's CPU seconds for this clip (read to written)
    lead_in_frames: int = 0  # of ``frames``, the --lead-in's: written, not solved

    @property
    def solved_frames(self) -> int:
        return self.frames - self.lead_in_frames


class ClipConverter:
    """Converts clips for one robot and model; build once per process (the solver is costly),
    then call :meth:`convert` per clip."""

    def __init__(self, options: ConvertOptions) -> None:
        from robot_retarget.pipeline.step import RetargetStep
        from robot_retarget.robot.loader import load_robot_config
        from robot_retarget.runtime.loader import load_runtime_model
        from robot_retarget.skeleton.canonical import default_canonical_skeleton

        self.options = options
        self.config = load_robot_config(options.robot)
        self.model = load_runtime_model(options.model)
        if options.canonical_input and getattr(self.model, "architecture", None) != "san":
            raise RetargetError(  # before the solver is built: a refused run costs nothing
                f"--canonical-input: for a skeleton-aware model (a san run), and model "
                f"{self.model.name} reads the canonical joints always: drop it"
            )
        self.step = RetargetStep(
            self.config,
            self.model,
            default_canonical_skeleton(),
            rate_hz=options.fps,
            foot_lock=options.foot_lock,
        )
        self.native_model = None if options.canonical_input else _skeleton_aware(self.model)

    def convert(
        self,
        job: ClipJob,
        progress: Progress | None = None,
        *,
        log: Callable[[str], None] | None = None,
    ) -> ClipReport:
        """Convert ``job.clip`` and write its outputs; errors come back in the report.
        ``log``: where a keypoint clip's input summary goes (the CLI prints it)."""
        cpu0 = time.process_time()
        try:
            report = self._convert(job, progress, log)
        except (RetargetError, OSError, ValueError) as exc:
            report = ClipReport(job.clip, job.out, error=str(exc))
        except (MemoryError, RecursionError) as exc:  # this clip only: the others go on
            what = "out of memory" if isinstance(exc, MemoryError) else "nested too deeply"
            report = ClipReport(job.clip, job.out, error=f"{what} ({exc})")
        return dataclasses.replace(report, cpu_s=time.process_time() - cpu0)

    def _convert(
        self, job: ClipJob, progress: Progress | None, log: Callable[[str], None] | None
    ) -> ClipReport:
        from robot_retarget.cli.output_paths import StagedWrites
        from robot_retarget.keypoints.lift import load_keypoint_motion
        from robot_retarget.motion.human_motion import load_bvh_motion, load_motion
        from robot_retarget.pipeline.convert import LEAD_IN_SPEED_FRACTION, convert_motion
        from robot_retarget.pipeline.robot_bvh import write_robot_bvh
        from robot_retarget.render.preview import render_preview
        from robot_retarget.sources.keypoints import is_keypoint_input

        opt, config, clip = self.options, self.config, job.clip
        network: _OwnSkeletonNetwork | None = None
        if is_keypoint_input(clip):
            lifted = load_keypoint_motion(
                clip,
                model=opt.keypoint_model,
                fps=opt.keypoint_fps,
                max_frames=opt.max_frames,
                image_planes=opt.keypoint_image_planes,
            )
            motion = lifted.motion
            if log is not None:
                log(
                    f"{clip}: {motion.num_frames} keypoint frames at {motion.fps:g} fps, "
                    f"{lifted.missing_fraction:.1%} of points missing, {lifted.frames_held} "
                    "frame(s) without a body (the last seen pose held, the first seen one "
                    "before it), "
                    f"{lifted.refused_points} point(s) no body could have made refused; "
                    + _camera_summary(lifted.camera, opt.keypoint_image_planes)
                )
        elif self.native_model is not None:
            bvh, motion = load_bvh_motion(clip, max_frames=opt.max_frames)
            network = self._read_on_own_skeleton(clip, bvh, motion, log)
        else:
            motion = load_motion(clip, max_frames=opt.max_frames)
        result = convert_motion(
            motion if network is None else network.motion,
            self.step,
            fps=opt.fps,
            progress=progress,
            lead_in_speed_fraction=LEAD_IN_SPEED_FRACTION if opt.lead_in else None,
            network=None if network is None else network.step,
            whole_clip_branches=opt.whole_clip_branches,
            lift_swing_feet=opt.lift_swing_feet,
            hold_double_support=opt.hold_double_support,
        )
        traj = result.trajectory
        folders = job.make_folders
        # All of a clip's outputs, or none: each is written to a temporary file next to it and
        # moved into place only when every one of them has been written.
        with StagedWrites(force=job.force) as stage:
            stage.write(
                job.out, partial(traj.write, overwrite=True), option="--out", make_folders=folders
            )
            if job.bvh_out is not None:
                stage.write(
                    job.bvh_out,
                    partial(write_robot_bvh, config=config, trajectory=traj, overwrite=True),
                    option="--bvh-out",
                    make_folders=folders,
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
                        title=f"{clip.name} → {config.name} ({self.model.name})",
                        overwrite=True,
                    ),
                    option="--preview",
                    make_folders=folders,
                )
        return ClipReport(
            clip,
            job.out,
            frames=result.frames,
            wall_s=result.wall_s,
            limits_ok=result.limits.ok,
            clipped_commands=result.safety_commands_clipped,
            clipped_joints=result.safety_joint_clips,
            fallbacks=result.fallbacks,
            position_excess_rad=result.limits.position_excess_rad,
            velocity_excess_rad=result.limits.velocity_excess_rad,
            lead_in_frames=result.lead_in_frames,
        )

    def _read_on_own_skeleton(
        self, clip: Path, bvh: BvhClip, motion: HumanMotion, log: Callable[[str], None] | None
    ) -> _OwnSkeletonNetwork | None:
        """The skeleton-aware model run over ``clip`` read on the file's own skeleton (``bvh``),
        at the output rate, with ``motion`` resampled to it; None (the canonical joints, with a
        note) when it has no encoder for that skeleton."""
        from robot_retarget.motion.native_pose import native_pose
        from robot_retarget.nn.inference import retarget_clip
        from robot_retarget.pipeline.precomputed_step import PrecomputedStep
        from robot_retarget.skeleton.armatures import TopologyError

        assert self.native_model is not None
        try:
            native = native_pose(bvh, motion)
        except TopologyError as exc:
            if log is not None:
                log(f"{clip}: not read on its own skeleton ({exc}); the canonical joints")
            return None
        domain = self.native_model.domain_of(native.topology)
        if domain is None:
            if log is not None:
                log(
                    f"{clip}: {self.model.name} has no encoder for its skeleton "
                    f"{native.topology.name!r}; it reads the canonical joints"
                )
            return None
        rate = self.options.fps or self.config.control_rate_hz
        m = motion if abs(motion.fps - rate) < 1e-9 else motion.resample(rate)
        native = native if m is motion else native.resample(motion.fps, rate)
        robot = self.step.robot_skeleton.offsets
        quats, root = retarget_clip(
            self.native_model, m.local_quats, m.root_pos, m.skeleton.offsets, robot, native=native
        )
        if log is not None:
            log(f"{clip}: read on its own skeleton ({domain}) by {self.model.name}")
        return _OwnSkeletonNetwork(m, PrecomputedStep(quats, root))


@dataclass(frozen=True)
class _OwnSkeletonNetwork:
    """A clip at the output rate and the network's frames for it, read on its own skeleton."""

    motion: HumanMotion
    step: PrecomputedStep


def _skeleton_aware(model: object) -> SAN | None:
    """The torch model behind ``model`` if it reads files on their own skeletons (SAN) and
    torch is installed; else None (the canonical joints, as everywhere else)."""
    from robot_retarget.runtime.model import RuntimeModel

    if isinstance(model, RuntimeModel) and model.architecture != "san":
        return None
    try:
        from robot_retarget.nn.inference import LoadedModel, load_model
        from robot_retarget.nn.models.san import SAN
    except ImportError:
        return None
    if isinstance(model, LoadedModel):
        return model.model if isinstance(model.model, SAN) else None
    assert isinstance(model, RuntimeModel)
    from robot_retarget.runtime.loader import CHECKPOINT_DIR

    if model.path is None:
        return None
    shipped = model.path.resolve().parent == CHECKPOINT_DIR.resolve()
    if model.path.suffix != ".pt" and not shipped:
        # A runtime file the user gave reads the canonical joints wherever it lies: the same
        # bytes had given other trajectories (up to pi rad) with a .pt of its name beside them.
        # Its own skeleton is read from the .pt checkpoint (--model RUN/best.pt).
        return None
    source = model.path.with_suffix(".pt")
    try:
        loaded = load_model(str(source) if source.is_file() else model.name)
    except ModelLoadError:
        return None  # only its numpy runtime is here: the canonical joints
    return loaded.model if isinstance(loaded.model, SAN) else None

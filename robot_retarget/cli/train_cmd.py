"""``train --model pmnet --data DIR --out runs/NAME``: train a retargeting network.

Prints a progress bar (stderr) with the running losses and the latest validation score;
writes checkpoints and logs into the run folder (see robot_retarget.nn.train). ``--resume``
continues a run from its last checkpoint with the stored settings, or with a larger --steps.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import shlex
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robot_retarget.cli.data_dir import add_data_argument
from robot_retarget.errors import RetargetError
from robot_retarget.number_args import (
    int_at_least,
    non_negative_float,
    non_negative_int,
    positive_float,
    positive_int,
    torch_device,
)

if TYPE_CHECKING:
    from robot_retarget.nn.motion_augmentation import MotionAugmentation

NAME = "train"
HELP = "Train a retargeting network (nkn, pmnet) on a folder of BVH clips."
_DISTILL_WEIGHT = 0.5  # the teacher's default share of the target (--distill-weight)


class TrainArgumentError(RetargetError):
    """A command-line value cannot be used (names the option and what is allowed)."""


def _model_config(pairs: list[str], option: str = "--model-config") -> dict[str, Any]:
    """KEY=VALUE strings → dict; values parsed as JSON when they are JSON (numbers, bools)."""
    out: dict[str, Any] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise TrainArgumentError(f"{option} {pair!r}: expected KEY=VALUE, e.g. hidden_size=256")
        try:
            out[key] = json.loads(value)
        except json.JSONDecodeError:
            out[key] = value
    return out


def configure(parser: argparse.ArgumentParser) -> None:
    from robot_retarget.nn.dataset import (
        DEFAULT_FPS,
        DEFAULT_ROBOTS,
        DEFAULT_VALIDATION_SUBJECTS,
        DEFAULT_WINDOW_FRAMES,
    )

    parser.add_argument(
        "--model",
        required=True,
        choices=("nkn", "pmnet", "residual", "tdcn", "san", "agnostic2d"),
        help="network (agnostic2d: the 2D keypoint model, robot_retarget.nn.agnostic2d_training)",
    )
    add_data_argument(parser)
    parser.add_argument("--out", required=True, help="run folder, e.g. runs/pmnet-1")
    parser.add_argument("--resume", action="store_true", help="continue the run in --out")
    parser.add_argument(
        "--force",
        action="store_true",
        help="start a new run in an --out that holds one (its checkpoints and logs are deleted "
        "first; without --force or --resume such a folder is refused)",
    )
    parser.add_argument(
        "--steps", type=positive_int, default=20000, help="total optimisation steps"
    )
    parser.add_argument("--batch-size", type=positive_int, default=32)
    parser.add_argument(
        "--window", type=int_at_least(2), default=DEFAULT_WINDOW_FRAMES, help="frames (≥ 2)"
    )
    parser.add_argument("--fps", type=positive_float, default=DEFAULT_FPS, help="common frame rate")
    parser.add_argument(
        "--val-subjects",
        default=",".join(DEFAULT_VALIDATION_SUBJECTS),
        help="comma-separated validation subjects, never trained on (default %(default)s; "
        "empty for no validation: best.pt is then the last checkpoint)",
    )
    parser.add_argument(
        "--exclude-subjects",
        default="",
        help="comma-separated subjects left out of the data entirely, neither trained nor "
        "validated on (a held-out test fold; crossval passes it)",
    )
    parser.add_argument(
        "--robots",
        default=",".join(DEFAULT_ROBOTS),
        help="robot configs whose canonical skeletons are training targets (default %(default)s;"
        " empty for none)",
    )
    parser.add_argument(
        "--val-every", type=positive_int, default=500, help="steps between validations"
    )
    parser.add_argument("--checkpoint-every", type=positive_int, default=500)
    parser.add_argument("--log-every", type=positive_int, default=25)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--device", type=torch_device, default="cpu", help="cpu (default), cuda, cuda:N or mps"
    )
    parser.add_argument(
        "--lr", type=positive_float, default=1e-4, help="Adam learning rate (papers: 1e-4)"
    )
    parser.add_argument(
        "--model-config",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="model constructor argument, e.g. hidden_size=256 (repeatable)",
    )
    parser.add_argument(
        "--live-noise",
        type=float,
        default=0.0,
        metavar="SHARE",
        help="residual model: the share (0-1) of denoising samples corrupted as a live "
        "position sender's (jitter, frozen joints, swapped limbs, bone-length noise, solved back "
        "to rotations as the live path does) instead of with SAN's rotation noise",
    )
    parser.add_argument(
        "--loss-weight",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override one of the model's loss weights, e.g. bone=3 (repeatable; defaults: "
        "the papers' for nkn and pmnet, robot_retarget.nn.models.training for residual)",
    )
    parser.add_argument(
        "--disc-config",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="discriminator constructor argument, e.g. channels=[16,32,64,128] (repeatable)",
    )
    parser.add_argument(
        "--same-skeleton-recon",
        type=non_negative_float,
        default=0.0,
        metavar="WEIGHT",
        help="extra B = A reconstruction loss on the retargeted pose (deviation from the "
        "papers; default 0 = off; see robot_retarget.nn.train.same_skeleton_step)",
    )
    parser.add_argument(
        "--max-frames", type=positive_int, default=None, help="first frames per clip"
    )
    parser.add_argument("--cache-dir", default=None, help="preprocessed-data cache folder")
    parser.add_argument("--threads", type=positive_int, default=None, help="torch CPU threads")
    parser.add_argument(
        "--loader-workers",
        type=non_negative_int,
        default=0,
        metavar="N",
        help="agnostic2d: N processes render the camera views ahead of the training step "
        "(default 0: in the training process; the batches are the same either way)",
    )
    parser.add_argument(
        "--mirror-probability",
        type=float,
        default=0.0,
        metavar="P",
        help="agnostic2d: chance a training window is mirrored left-right (default 0)",
    )
    parser.add_argument(
        "--speed-range",
        default="1,1",
        metavar="LOW,HIGH",
        help="agnostic2d: playback speed factors of training windows, drawn log-uniformly "
        "(default 1,1: unchanged; e.g. 0.8,1.25)",
    )
    parser.add_argument(
        "--arm-mix-probability",
        type=float,
        default=0.0,
        metavar="P",
        help="agnostic2d: chance, per arm of a training window, that it takes the arm of "
        "another random window (default 0)",
    )
    parser.add_argument(
        "--causal-probability",
        type=float,
        default=None,
        metavar="P",
        help="agnostic2d (causal models): share of batches run causally, as stream runs the "
        "model; the rest pool the static codes over the whole window (default 0.5)",
    )
    parser.add_argument(
        "--init-from",
        default=None,
        metavar="CKPT",
        help="agnostic2d: start from this keypoint checkpoint's weights and architecture "
        "(fine-tuning; e.g. robot_retarget/data/checkpoints/agnostic2d.pt)",
    )
    parser.add_argument(
        "--distill-from",
        action="append",
        default=[],
        metavar="CKPT",
        help="agnostic2d: a keypoint checkpoint whose answer on each training window is a second "
        "target (knowledge distillation); repeat the option, one file each, for several, their "
        "answers averaged (e.g. convert's four centred models: --distill-from "
        "robot_retarget/data/checkpoints/agnostic2d_clip.pt --distill-from …-s1.pt …)",
    )
    parser.add_argument(
        "--distill-weight",
        type=float,
        default=None,
        metavar="W",
        help="agnostic2d with --distill-from: the teacher's share of the target, the truth's "
        f"1 - W (default {_DISTILL_WEIGHT})",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


# A run holding any of these can be resumed or scored: a failed run keeps its files then.
_CHECKPOINTS = ("last.pt", "best.pt", "trainer_state.pt")


@contextlib.contextmanager
def _run_folder(args: argparse.Namespace) -> Iterator[None]:
    """Claim --out (:func:`_claim_run_folder`) for the training inside. A new run that stops
    before its first checkpoint (refused, failed or interrupted) takes the files it wrote
    (config.json, the log) with it, so that running again needs no --force, and leaves no
    empty folder behind where there was none."""
    from robot_retarget.nn.run_folder import clear_run

    out = Path(args.out)
    existed = out.exists()
    _claim_run_folder(args)
    try:
        yield
    except BaseException:
        if not args.resume and not any((out / name).exists() for name in _CHECKPOINTS):
            with contextlib.suppress(OSError):
                clear_run(out)
        if not existed:
            with contextlib.suppress(OSError):
                out.rmdir()  # only while empty
        raise


def _claim_run_folder(args: argparse.Namespace) -> None:
    """Before any work (--steps is checked as the command line is read): --out is a folder the
    run may write — not one that holds another run unless --resume continues it or --force
    replaces it (deleted by the training itself once its settings, data, model and optimizer
    are accepted, so a refused run deletes nothing)."""
    from robot_retarget.nn.run_folder import run_files

    if args.force and args.resume:
        raise TrainArgumentError("--force starts the run again, --resume continues it: pass one")
    if args.force and int(os.environ.get("WORLD_SIZE", "1")) > 1:
        raise TrainArgumentError(
            "--force under torchrun: delete the run folder's files first, or name a new --out"
        )
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise TrainArgumentError(f"--out {out}: a file, not a folder; name a folder for the run")
    held = [p.name for p in run_files(out)]
    if held and not args.resume and not args.force and os.environ.get("RANK", "0") == "0":
        raise TrainArgumentError(
            f"--out {out} already holds a run ({', '.join(held)}): pass --resume to continue "
            "it, --force to start a new one there (its files are deleted), or name another "
            "folder"
        )
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise TrainArgumentError(f"--out {out}: cannot create the run folder ({e})") from e


def _check_held_out(args: argparse.Namespace) -> None:
    """A subject left out entirely (--exclude-subjects) cannot also be validated on: said
    before the data load, naming both options (the split said the subject was not in the
    data)."""
    validation = [s for s in args.val_subjects.split(",") if s]
    both = sorted(set(validation) & {s for s in args.exclude_subjects.split(",") if s})
    if both and not args.resume:
        raise TrainArgumentError(
            f"--exclude-subjects leaves out {', '.join(both)}, which --val-subjects "
            f"({','.join(validation)}) validates on: a subject is either validated on or left "
            "out; pass --val-subjects without it (empty for no validation)"
        )


def _bar(done: int, total: int, width: int = 24) -> str:
    filled = int(width * done / max(total, 1))
    return "[" + "#" * filled + "." * (width - filled) + "]"


def _agnostic2d_options_given(args: argparse.Namespace) -> list[str]:
    """The keypoint model's options this command line sets, in --help's order."""
    given = {
        "--mirror-probability": args.mirror_probability != 0.0,
        "--speed-range": args.speed_range != "1,1",
        "--arm-mix-probability": bool(args.arm_mix_probability),
        "--causal-probability": args.causal_probability is not None,
        "--init-from": args.init_from is not None,
        "--distill-from": bool(args.distill_from),
        "--distill-weight": args.distill_weight is not None,
    }
    return [option for option, set_ in given.items() if set_]


# Command-line options that shape a run, and the TrainConfig field each sets: on --resume, one
# given with another value than the run was started with is refused (it was silently ignored).
_RESUMED_OPTIONS: dict[str, str] = {
    "data": "data_dir", "batch_size": "batch_size", "window": "window_frames", "fps": "fps",
    "val_subjects": "validation_subjects", "robots": "robots", "val_every": "val_every",
    "checkpoint_every": "checkpoint_every", "log_every": "log_every", "seed": "seed",
    "lr": "lr", "model_config": "model_config", "disc_config": "discriminator_config",
    "loss_weight": "loss_weights", "same_skeleton_recon": "same_skeleton_recon",
    "max_frames": "max_frames", "exclude_subjects": "exclude_subjects",
    "live_noise": "live_noise",
}  # fmt: skip


def _check_resumed_settings(args: argparse.Namespace, asked: Any, stored: Any) -> None:
    """Refuse an option given on a --resume command line whose value differs from the run's."""
    defaults = argparse.ArgumentParser()
    configure(defaults)
    changed = []
    for dest, field in _RESUMED_OPTIONS.items():
        given = getattr(args, dest) != defaults.get_default(dest)
        if given and getattr(asked, field) != getattr(stored, field):
            option = "--" + dest.replace("_", "-")
            changed.append(f"{option} ({getattr(asked, field)!r}, the run has "
                           f"{getattr(stored, field)!r})")  # fmt: skip
    if changed:
        raise TrainArgumentError(
            f"--resume continues the run in {args.out} with the settings it was started with; "
            f"{_and(changed)} {'differs' if len(changed) == 1 else 'differ'}: drop "
            f"{'it' if len(changed) == 1 else 'them'}, or start a new run (another --out, or "
            "--force)"
        )


def _and(items: list[str]) -> str:
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} and {items[-1]}"


def run(args: argparse.Namespace) -> int:
    import torch

    from robot_retarget.nn.train import TrainConfig, TrainProgress, load_run, train

    if args.threads is not None:
        torch.set_num_threads(args.threads)
    _check_held_out(args)
    if args.model == "agnostic2d":
        return _run_agnostic2d(args)
    given = _agnostic2d_options_given(args)
    if given:
        raise TrainArgumentError(
            f"{_and(given)} {'is' if len(given) == 1 else 'are'} agnostic2d's; {args.model} "
            f"does not use {'it' if len(given) == 1 else 'them'} (drop "
            f"{'it' if len(given) == 1 else 'them'}, or pass --model agnostic2d)"
        )
    robots = tuple(r for r in args.robots.split(",") if r)
    asked = TrainConfig(
        model=args.model,
        **_run_settings(args),
        robots=robots,
        checkpoint_every=args.checkpoint_every,
        log_every=args.log_every,
        discriminator_config=_model_config(args.disc_config),
        loss_weights=_model_config(args.loss_weight, "--loss-weight"),
        same_skeleton_recon=args.same_skeleton_recon,
        live_noise=args.live_noise,
    )
    if args.resume and Path(args.out, "config.json").is_file():
        stored, _ = load_run(args.out)
        if stored.model != args.model:
            raise TrainArgumentError(
                f"--resume: the run in {args.out} trains {stored.model}, not {args.model}; "
                f"pass --model {stored.model}"
            )
        _check_resumed_settings(args, asked, stored)
        done = _checkpointed_step(Path(args.out)) or 0
        if args.steps <= done:
            raise TrainArgumentError(
                f"--resume: the run in {args.out} is already at step {done}, and --steps "
                f"{args.steps} asks for no more; pass a larger --steps to train on"
            )
        # Resume with the stored settings; only --steps (to extend a run), --device and the
        # cache folder change.
        config = TrainConfig.from_json(
            {**stored.to_json(), "steps": args.steps, "device": args.device,
             "cache_dir": args.cache_dir}
        )  # fmt: skip
    else:
        config = asked
        done = 0
    last_val: dict[str, float] = {}

    def show(p: TrainProgress) -> None:
        if p.validation is not None:
            last_val.update(p.validation)
        if args.quiet:
            return
        rate = p.elapsed_s / max(p.step - done, 1)  # this process's steps (a resume's too)
        loss = p.losses.get("total", float("nan"))
        val = f" val score {last_val['score']:.4f}" if last_val else ""
        _progress_line(
            p.step,
            p.total_steps,
            f"loss {loss:.4f}{val} ({p.elapsed_s:.0f} s, {rate * 1e3:.0f} ms/step)",
            last=p.validation is not None,
        )

    command = _command_line()
    with _run_folder(args):
        try:
            result = train(
                config, resume=args.resume, progress=show, command=command, fresh=args.force
            )
        except KeyboardInterrupt:
            _say_what_was_kept(Path(args.out))
            raise
    if os.environ.get("RANK", "0") != "0":
        return 0  # torchrun: rank 0 exports and reports the one run
    runtime = _export_best(result.best_path)
    print(
        json.dumps(
            {
                "out": str(result.out_dir),
                "best": str(result.best_path),
                "runtime": None if runtime is None else str(runtime),
                "last": str(result.last_path),
                "steps": result.steps,
                # null without a validation score (JSON has no Infinity: strict readers refuse it)
                "best_score": result.best_score if math.isfinite(result.best_score) else None,
                "data_hash": result.data_hash,
            }
        )
    )
    return 0


def _run_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The settings every kind of run reads the same way from the command line (the
    retargeting networks' TrainConfig and the keypoint model's KeypointTrainConfig)."""
    return {
        "data_dir": args.data,
        "out_dir": args.out,
        "steps": args.steps,
        "batch_size": args.batch_size,
        "window_frames": args.window,
        "fps": args.fps,
        "validation_subjects": tuple(s for s in args.val_subjects.split(",") if s),
        "exclude_subjects": tuple(s for s in args.exclude_subjects.split(",") if s),
        "val_every": args.val_every,
        "seed": args.seed,
        "lr": args.lr,
        "model_config": _model_config(args.model_config),
        "max_frames": args.max_frames,
        "cache_dir": args.cache_dir,
        "device": args.device,
    }


def _checkpointed_step(out: Path) -> int | None:
    """The step of the run folder's last checkpoint (trainer_state.pt), None without one."""
    import torch

    state = out / "trainer_state.pt"
    if not state.is_file():
        return None
    return int(torch.load(state, map_location="cpu", weights_only=True)["step"])


def _say_what_was_kept(out: Path) -> None:
    """After Ctrl-C: what the run folder holds (best.pt's runtime written too), and how to go
    on; a run stopped before its first checkpoint keeps nothing (see _run_folder)."""
    step = _checkpointed_step(out)
    if step is None:
        print(f"\ntrain interrupted before its first checkpoint: nothing kept in {out}",
              file=sys.stderr)  # fmt: skip
        return
    if (out / "best.pt").is_file():
        _export_best(out / "best.pt")
    print(
        f"\ntrain interrupted: {out} holds the checkpoints of step {step} (last.pt, and best.pt "
        "with its runtime best.npz); to go on, run the same command with --resume",
        file=sys.stderr,
    )


def _export_best(best: Path) -> Path | None:
    """best.pt → best.npz beside it (stream and convert it without torch); None, with a note,
    for an architecture that has no numpy runtime yet."""
    from robot_retarget.errors import ModelLoadError
    from robot_retarget.nn.export import export_runtime

    try:
        out, _ = export_runtime(best, force=True)
    except ModelLoadError as exc:
        print(f"note: {best} not exported ({exc})", file=sys.stderr)
        return None
    return out


def _progress_line(step: int, total: int, text: str, *, last: bool) -> None:
    """The progress bar on stderr, rewritten in place; a new line after a validation and at
    the end."""
    end = "\n" if last or step == total else ""
    print(f"\r{_bar(step, total)} {step}/{total} {text}", end=end, file=sys.stderr, flush=True)


def _command_line() -> str:
    """The command as the user can run it again (stored in the run's metadata)."""
    return "python launch.py " + shlex.join(sys.argv[1:]) if sys.argv[1:] else ""


def _motion_augmentation(
    mirror_probability: float, speed_range: str, arm_mix_probability: float = 0.0
) -> MotionAugmentation:
    from robot_retarget.nn.motion_augmentation import MotionAugmentation

    try:
        low, high = (float(v) for v in speed_range.split(","))
        return MotionAugmentation(mirror_probability, (low, high), arm_mix_probability)
    except ValueError as exc:
        raise TrainArgumentError(
            f"--mirror-probability {mirror_probability} / --speed-range {speed_range!r} / "
            f"--arm-mix-probability {arm_mix_probability}: {exc}; use probabilities in [0, 1] "
            "and LOW,HIGH with 0 < LOW ≤ HIGH, e.g. 0.8,1.25"
        ) from exc


# Options only the other models' loop reads (agnostic2d validates every --val-every steps,
# renders its own camera views and has no discriminator, robot targets or live-noise samples).
_NOT_AGNOSTIC2D = (
    "robots",
    "checkpoint_every",
    "log_every",
    "live_noise",
    "disc_config",
    "same_skeleton_recon",
)


def _options_agnostic2d_ignores(args: argparse.Namespace) -> list[str]:
    """Those of :data:`_NOT_AGNOSTIC2D` given away from their defaults."""
    defaults = argparse.ArgumentParser()
    configure(defaults)
    return [
        "--" + name.replace("_", "-")
        for name in _NOT_AGNOSTIC2D
        if getattr(args, name) != defaults.get_default(name)
    ]


def _run_agnostic2d(args: argparse.Namespace) -> int:
    """The 2D keypoint model has its own loop (two camera views per window, 3D targets)."""
    if args.distill_weight is not None and not args.distill_from:
        raise TrainArgumentError(
            f"--distill-weight {args.distill_weight} weighs a teacher's answer, and no "
            "--distill-from names one: add --distill-from CKPT, or drop --distill-weight"
        )
    from robot_retarget.nn.agnostic2d_training import (
        KeypointProgress,
        KeypointTrainConfig,
        train_agnostic2d,
    )

    if args.resume:
        raise TrainArgumentError("--resume is not supported for agnostic2d; start a new run")
    unused = _options_agnostic2d_ignores(args)
    if unused:
        raise TrainArgumentError(
            f"{', '.join(unused)}: only the other models' training reads "
            f"{'it' if len(unused) == 1 else 'them'}; agnostic2d validates and checkpoints "
            "every --val-every steps and has no robot targets, discriminator or live noise: "
            f"drop {'it' if len(unused) == 1 else 'them'}"
        )
    weights = _model_config(args.loss_weight, "--loss-weight")
    unknown = sorted(set(weights) - {"triplet", "direction", "limb"})
    if unknown:
        raise TrainArgumentError(
            f"--loss-weight {unknown}: agnostic2d's weights are triplet, direction and limb"
        )
    config = KeypointTrainConfig(
        augment=_motion_augmentation(
            args.mirror_probability, args.speed_range, args.arm_mix_probability
        ),
        triplet_weight=float(weights.get("triplet", 0.1)),
        direction_weight=float(weights.get("direction", 1.0)),
        limb_weight=float(weights.get("limb", 0.0)),
        **_run_settings(args),
        loader_workers=args.loader_workers,
        causal_probability=args.causal_probability,
        init_from=args.init_from,
        distill_from=tuple(args.distill_from),
        distill_weight=_DISTILL_WEIGHT if args.distill_weight is None else args.distill_weight,
    )

    def show(p: KeypointProgress) -> None:
        if args.quiet:
            return
        val = ""
        if p.validation:
            causal = p.validation.get("direction_error_deg_causal")  # absent: a centred model
            val = " val " + ("" if causal is None else f"{causal:.2f}° causal / ")
            val += f"{p.validation['direction_error_deg_clip']:.2f}° clip"
        _progress_line(
            p.step,
            p.total_steps,
            f"loss {p.losses['total']:.4f}{val} ({p.elapsed_s:.0f} s)",
            last=p.validation is not None,
        )

    with _run_folder(args):
        summary = train_agnostic2d(config, progress=show, command=_command_line(), fresh=args.force)
    print(json.dumps(summary))
    return 0

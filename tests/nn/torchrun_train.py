"""Run by tests/nn/test_train_torchrun.py under ``torchrun``: a tiny residual-model training
run (the same configuration the test runs in one process). Not a test module itself."""

from __future__ import annotations

import argparse
import dataclasses

from robot_retarget.nn.train import TrainConfig, train


def tiny_config(mocap_dir: str, out: str, cache: str, steps: int) -> TrainConfig:
    return TrainConfig(
        model="residual",
        data_dir=mocap_dir,
        out_dir=out,
        steps=steps,
        batch_size=4,
        window_frames=8,
        validation_subjects=("s2",),
        robots=("op3",),
        val_every=2,
        val_batches=1,
        checkpoint_every=2,
        log_every=1,
        model_config={"hidden_size": 16, "num_layers": 2, "denoiser_hidden": 8},
        cache_dir=cache,
        lr=1e-3,
        # The corruption noise is drawn per shard (robot_retarget.nn.distributed): without the
        # terms it feeds, one step is the same computation on any number of ranks.
        loss_weights={"denoise": 0.0},
    )


def main() -> None:
    import torch

    torch.set_num_threads(1)
    p = argparse.ArgumentParser()
    p.add_argument("mocap_dir")
    p.add_argument("out")
    p.add_argument("cache")
    p.add_argument("--steps", type=int, default=4)
    p.add_argument("--resume", action="store_true")
    args = p.parse_args()
    cfg = tiny_config(args.mocap_dir, args.out, args.cache, args.steps)
    train(dataclasses.replace(cfg), resume=args.resume)


if __name__ == "__main__":
    main()

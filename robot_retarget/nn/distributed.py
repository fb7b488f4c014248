"""Data-parallel training under ``torchrun``: one process per rank, one shard of each batch.

``torchrun --nproc-per-node N launch.py train ...`` starts N copies of the training loop;
:meth:`DataParallel.from_env` reads the ranks torchrun sets (``WORLD_SIZE``, ``RANK``,
``LOCAL_RANK``) and joins the process group (gloo on CPU, NCCL on CUDA). Every rank draws the
same global batch (batch n is a pure function of (seed, n)) and trains on its contiguous
1/N of it; before each optimiser step the gradients are averaged over the ranks, so every
rank takes the same step and the weights stay identical (they are broadcast from rank 0 once
at the start). Only rank 0 writes files; the checkpoints and the trainer state are the same
whatever the world size, so ``--resume`` works across world sizes.

Not bit-identical to one process: each rank clips its own gradient norm before the average,
and the per-step noise (the residual model's input corruption) is drawn for a shard's shape,
so rank r's samples see other noise than in one process. The difference is measured by the
torchrun test (tests/nn/test_train_torchrun.py) and stated in its tolerance.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass

import torch

from robot_retarget.errors import RetargetError
from robot_retarget.nn.models.batch import RetargetBatch


class DataParallelError(RetargetError):
    """A data-parallel run cannot go as asked: ``world_size`` ranks, ``reason`` why."""

    def __init__(self, message: str, *, world_size: int) -> None:
        self.world_size = world_size
        self.reason = message
        super().__init__(f"torchrun with {world_size} processes: {message}")


@dataclass(frozen=True)
class DataParallel:
    """This process's rank among ``world_size`` (a single process: rank 0 of 1)."""

    rank: int = 0
    world_size: int = 1
    local_rank: int = 0

    @property
    def is_main(self) -> bool:
        return self.rank == 0

    @property
    def active(self) -> bool:
        return self.world_size > 1

    @classmethod
    def from_env(cls, device: str) -> DataParallel:
        """The ranks torchrun set, with the process group joined; one process without them."""
        world = int(os.environ.get("WORLD_SIZE", "1"))
        if world <= 1:
            return cls()
        import torch.distributed as dist

        if not dist.is_initialized():
            dist.init_process_group("nccl" if device.startswith("cuda") else "gloo")
        return cls(dist.get_rank(), dist.get_world_size(), int(os.environ.get("LOCAL_RANK", "0")))

    def device(self, name: str) -> str:
        """``cuda`` becomes this rank's GPU (``cuda:LOCAL_RANK``)."""
        return f"cuda:{self.local_rank}" if self.active and name == "cuda" else name

    def check_batch_size(self, batch_size: int) -> None:
        if batch_size % self.world_size:
            raise DataParallelError(
                f"--batch-size {batch_size} does not split into {self.world_size} equal shards; "
                f"use a multiple of {self.world_size}",
                world_size=self.world_size,
            )

    def shard(self, batch: RetargetBatch) -> RetargetBatch:
        """This rank's contiguous 1/world_size of the global batch."""
        if not self.active:
            return batch
        n = batch.src_local_quats.shape[0] // self.world_size
        lo, hi = self.rank * n, (self.rank + 1) * n
        parts = {
            f.name: getattr(batch, f.name)[lo:hi]
            for f in dataclasses.fields(batch)
            if isinstance(getattr(batch, f.name), torch.Tensor)
        }
        return dataclasses.replace(batch, **parts)

    def average_gradients_before_step(self, optimizer: torch.optim.Optimizer) -> None:
        """Average every parameter's gradient over the ranks before each ``step()``. Every
        rank reduces every parameter (a zero stands for a missing gradient) so the ranks'
        collectives always match; a parameter no rank has a gradient for keeps none."""
        if not self.active:
            return
        import torch.distributed as dist

        params = [p for group in optimizer.param_groups for p in group["params"]]
        world = self.world_size

        def hook(_opt: torch.optim.Optimizer, _args: object, _kwargs: object) -> None:
            has = torch.tensor([p.grad is not None for p in params], dtype=torch.float32)
            dist.all_reduce(has)
            for p, n in zip(params, has.tolist(), strict=True):
                if n == 0:
                    continue
                grad = p.grad if p.grad is not None else torch.zeros_like(p)
                dist.all_reduce(grad)
                grad /= world
                p.grad = grad

        optimizer.register_step_pre_hook(hook)

    def broadcast(self, *modules: torch.nn.Module | None) -> None:
        """Rank 0's parameters and buffers to every rank (one starting point)."""
        if not self.active:
            return
        import torch.distributed as dist

        for module in modules:
            if module is None:
                continue
            for t in [*module.parameters(), *module.buffers()]:
                dist.broadcast(t.data, src=0)

    def mean(self, values: dict[str, float]) -> dict[str, float]:
        """The ranks' mean of each value (losses for the log)."""
        if not self.active or not values:
            return values
        import torch.distributed as dist

        keys = list(values)  # the same order on every rank (the same code made them)
        t = torch.tensor([values[k] for k in keys], dtype=torch.float64)
        dist.all_reduce(t)
        return {k: float(v) / self.world_size for k, v in zip(keys, t.tolist(), strict=True)}

    def barrier(self) -> None:
        if self.active:
            import torch.distributed as dist

            dist.barrier()

"""Whether torch can run on a ``--device`` (train, crossval, the keypoint model's training).

The name is checked as the command line is read (:func:`robot_retarget.number_args.torch_device`);
whether this machine's torch has that device is checked here, before any data is read: a CUDA
device torch cannot see, a CUDA index past the last, or MPS on a torch without it had ended in
torch's traceback (MPS) or named the wrong device (``cuda:0`` as ``cuda``).
"""

from __future__ import annotations

import torch


def device_problem(name: str) -> str | None:
    """Why ``--device name`` cannot run here, or None if it can."""
    kind, _, index = name.partition(":")
    if kind == "cuda":
        if not torch.cuda.is_available():
            return f"--device {name}: torch sees no CUDA device here; use cpu"
        if index and int(index) >= torch.cuda.device_count():
            return (
                f"--device {name}: torch sees {torch.cuda.device_count()} CUDA device(s), "
                f"cuda:0 … cuda:{torch.cuda.device_count() - 1}"
            )
    if kind == "mps" and not torch.backends.mps.is_available():
        return f"--device {name}: this torch has no MPS (Apple GPU) support here; use cpu"
    return None

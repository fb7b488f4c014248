"""--device is checked against this machine's torch before any data is read."""

from __future__ import annotations

from unittest import mock

import torch

from robot_retarget.nn.device import device_problem


def test_cpu_always_runs() -> None:
    assert device_problem("cpu") is None


def test_a_device_torch_does_not_have_is_named_as_given() -> None:
    with mock.patch.object(torch.cuda, "is_available", return_value=False):
        problem = device_problem("cuda:0")
    assert problem is not None
    assert problem.startswith("--device cuda:0: torch sees no CUDA device")
    with mock.patch.object(torch.backends.mps, "is_available", return_value=False):
        problem = device_problem("mps")  # had ended in torch's RuntimeError mid-run
    assert problem is not None
    assert "no MPS" in problem
    with (
        mock.patch.object(torch.cuda, "is_available", return_value=True),
        mock.patch.object(torch.cuda, "device_count", return_value=2),
    ):
        assert device_problem("cuda:1") is None
        problem = device_problem("cuda:2")
    assert problem is not None
    assert "cuda:0 … cuda:1" in problem

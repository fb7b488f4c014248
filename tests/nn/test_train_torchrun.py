"""``torchrun --nproc-per-node 2``: two ranks train as one process does (same seed, same
global batch), rank 0 alone writes the run folder, and a run resumes on another world size.

The tiny residual run of tests/nn/torchrun_train.py, without the corruption-noise terms
(their noise is drawn per shard, see robot_retarget.nn.distributed): then a step is the same
computation on one or two ranks and the weights after 4 Adam steps (lr 1e-3, so each step
moves a weight by up to ~1e-3) agree to 1e-4, a tenth of one step: an empirical bound.
Measured: 1.4e-6 on one machine, 4.8e-5 on another (2 of 66 and 30 of 5280 weights above 1e-5).
The sums run in another order on two ranks, and Adam's normalised step can turn that float32
noise into as much as ~lr for a weight whose gradient is nearly zero; a rank training on other
data moves most weights by ~lr.
"""

from __future__ import annotations

import csv
import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from robot_retarget.nn.checkpoint import load_checkpoint
from robot_retarget.nn.distributed import DataParallel, DataParallelError
from robot_retarget.nn.train import train

sys.path.insert(0, str(Path(__file__).resolve().parent))
from torchrun_train import tiny_config

REPO = Path(__file__).resolve().parents[2]
SCRIPT = Path(__file__).resolve().parent / "torchrun_train.py"
TIME_LIMIT_S = 300
ATOL = 1e-4


def _torchrun(mocap: Path, out: Path, cache: Path, steps: int) -> None:
    if not torch.distributed.is_available() or not torch.distributed.is_gloo_available():
        pytest.skip("this torch build has no gloo backend for CPU process groups")
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]),
    }
    cmd = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc-per-node", "2",
           str(SCRIPT), str(mocap), str(out), str(cache), "--steps", str(steps)]  # fmt: skip
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=240)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]


def _assert_same_weights(a: Path, b: Path) -> None:
    sa = load_checkpoint(a).model.state_dict()
    sb = load_checkpoint(b).model.state_dict()
    assert sa.keys() == sb.keys()
    for key in sa:
        torch.testing.assert_close(sa[key], sb[key], rtol=0, atol=ATOL, msg=key)


def test_two_ranks_train_as_one_process_and_resume_on_one(
    mocap_dir: Path, cache_dir: Path, tmp_path: Path
) -> None:
    one = train(tiny_config(str(mocap_dir), str(tmp_path / "one"), str(cache_dir), steps=4))

    _torchrun(mocap_dir, tmp_path / "two", cache_dir, steps=4)
    _assert_same_weights(one.last_path, tmp_path / "two" / "last.pt")
    assert load_checkpoint(tmp_path / "two" / "last.pt").metadata["world_size"] == 2
    rows = list(csv.DictReader((tmp_path / "two" / "log.csv").open()))
    keys = [(r["step"], r["split"], r["metric"]) for r in rows]
    assert len(keys) == len(set(keys))  # one log, written by rank 0 alone
    assert len(list((tmp_path / "two").glob("events.out.tfevents.*"))) == 1

    # Two ranks for 2 steps, then one process resumes to step 4: as if never interrupted.
    _torchrun(mocap_dir, tmp_path / "resumed", cache_dir, steps=2)
    cfg = tiny_config(str(mocap_dir), str(tmp_path / "resumed"), str(cache_dir), steps=4)
    resumed = train(cfg, resume=True)
    assert resumed.steps == 4
    _assert_same_weights(one.last_path, resumed.last_path)


def test_single_process_is_rank_0_of_1() -> None:
    dp = DataParallel.from_env("cpu") if "WORLD_SIZE" not in os.environ else DataParallel()
    assert (dp.rank, dp.world_size, dp.is_main, dp.active) == (0, 1, True, False)


def test_batch_must_split_evenly_over_ranks() -> None:
    with pytest.raises(DataParallelError, match="multiple of 2") as info:
        DataParallel(rank=0, world_size=2).check_batch_size(5)
    assert info.value.world_size == 2


def test_models_with_conditional_updates_are_refused_on_several_ranks(tmp_path: Path) -> None:
    from robot_retarget.nn.train import _check_data_parallel

    two = DataParallel(rank=0, world_size=2)
    cfg = tiny_config("data", str(tmp_path), str(tmp_path), steps=1)
    _check_data_parallel(cfg, two)  # residual: every step updates on every rank
    with pytest.raises(DataParallelError, match="--model nkn"):
        _check_data_parallel(dataclasses.replace(cfg, model="nkn"), two)
    with pytest.raises(DataParallelError, match="same-skeleton"):
        _check_data_parallel(dataclasses.replace(cfg, same_skeleton_recon=1.0), two)

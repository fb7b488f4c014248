"""``convert DIR --workers N``: the manifest makes a re-run skip done clips and retry failed
ones; without Ray, more than one worker says how to install the [scale] extra."""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

import pytest

from robot_retarget.cli import convert_cmd
from robot_retarget.errors import RetargetError
from robot_retarget.pipeline.clip_pool import ScaleExtraMissingError
from robot_retarget.pipeline.manifest import MANIFEST_NAME, ManifestError

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"


def _run(*argv: str) -> int:
    parser = argparse.ArgumentParser()
    convert_cmd.configure(parser)
    return convert_cmd.run(parser.parse_args(list(argv)))


@pytest.fixture
def clips(tmp_path: Path) -> Path:
    folder = tmp_path / "in"
    (folder / "sub").mkdir(parents=True)
    shutil.copy(FIXTURES / "tiny_walk.bvh", folder / "tiny_walk.bvh")
    shutil.copy(FIXTURES / "malformed" / "nan_value.bvh", folder / "sub" / "broken.bvh")
    return folder


def test_without_ray_more_workers_say_how_to_install_it(
    clips: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray → ImportError
    out = tmp_path / "out"
    with pytest.raises(ScaleExtraMissingError, match=r"pip install") as info:
        _run(str(clips), "--out", str(out), "--workers", "2")
    assert info.value.workers == 2
    assert "[scale]" in info.value.install_command
    assert not out.exists()  # refused before any work


def test_workers_need_a_folder(tmp_path: Path) -> None:
    with pytest.raises(RetargetError, match="folder"):
        _run(str(FIXTURES / "tiny_walk.bvh"), "--out", str(tmp_path / "a.npz"), "--workers", "1")


def test_rerun_skips_done_clips_and_retries_failed_ones(
    clips: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert _run(str(clips), "--out", str(out), "--workers", "1") == 1  # one clip fails
    manifest = json.loads((out / MANIFEST_NAME).read_text())
    status = {e["clip"]: e["status"] for e in manifest["clips"]}
    assert status == {"tiny_walk.bvh": "done", "sub/broken.bvh": "failed"}
    failed = next(e for e in manifest["clips"] if e["status"] == "failed")
    assert failed["error"]
    assert not (out / "sub" / "broken.npz").exists()
    done = out / "tiny_walk.npz"
    mtime = done.stat().st_mtime_ns

    shutil.copy(FIXTURES / "mixamo.bvh", clips / "sub" / "broken.bvh")  # fixed
    capsys.readouterr()
    assert _run(str(clips), "--out", str(out), "--workers", "1") == 0  # no --force needed
    err = capsys.readouterr().err
    assert "1 already done" in err
    assert "1 to convert" in err
    assert done.stat().st_mtime_ns == mtime
    assert (out / "sub" / "broken.npz").is_file()
    manifest = json.loads((out / MANIFEST_NAME).read_text())
    assert {e["status"] for e in manifest["clips"]} == {"done"}

    with pytest.raises(ManifestError, match="max_frames"):
        _run(str(clips), "--out", str(out), "--workers", "1", "--max-frames", "5")
    # Outputs made without the network's foot lock are not mixed with ones made with it.
    with pytest.raises(ManifestError, match="foot_lock"):
        _run(str(clips), "--out", str(out), "--workers", "1", "--foot-lock")


def test_outputs_the_job_did_not_make_still_need_force(clips: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "tiny_walk.npz").write_bytes(b"someone else's file")
    with pytest.raises(RetargetError, match="--force"):
        _run(str(clips), "--out", str(out), "--workers", "1")
    assert (out / "tiny_walk.npz").read_bytes() == b"someone else's file"

"""An option the input or backend would ignore is a one-line error naming it, before any
work, not a silent no-op (convert, stream, demo)."""

from __future__ import annotations

from pathlib import Path

import pytest

from robot_retarget.cli.main import main

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
WALK = FIXTURES / "motion" / "tiny_walk.bvh"


@pytest.mark.parametrize(
    ("extra", "out_name", "says"),
    [
        (["--format", "csv"], "a.npz", "--format csv: for folder input"),
        (["--keypoint-model", "agnostic2d"], "a.npz", "--keypoint-model: for 2D keypoint input"),
        (["--keypoint-fps", "25", "--no-image-planes"], "a.npz",
         "--keypoint-fps, --no-image-planes: for 2D keypoint input"),
    ],
)  # fmt: skip
def test_convert_refuses_options_a_bvh_clip_ignores(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], out_name: str, says: str
) -> None:
    out = tmp_path / out_name
    assert main(["convert", str(WALK), "--out", str(out), *extra]) != 0
    assert says in capsys.readouterr().err
    assert not out.exists()


def test_convert_refuses_a_file_name_for_a_folder_and_canonical_input_for_keypoints(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "clips"
    folder.mkdir()
    (folder / "a.bvh").write_bytes(WALK.read_bytes())
    assert main(["convert", str(folder), "--out", str(tmp_path / "lib.npz")]) != 0
    assert "a folder of clips is written to a folder" in capsys.readouterr().err
    assert not (tmp_path / "lib.npz").exists()
    keypoints = next((FIXTURES / "keypoints").glob("*.jsonl"))
    assert main(["convert", str(keypoints), "--out", str(tmp_path / "k.npz"),
                 "--canonical-input"]) != 0  # fmt: skip
    assert "--canonical-input: for BVH input" in capsys.readouterr().err
    # The same format named twice is no conflict.
    assert main(["convert", str(WALK), "--out", str(tmp_path / "b.csv"), "--format", "csv"]) == 0


def test_stream_and_demo_refuse_options_they_would_ignore(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["stream", "--backend", "sim", "--port", "/dev/ttyNOPE",
                 "--source", f"replay:{WALK}", "--duration", "1"]) != 0  # fmt: skip
    assert "--port names the servos' serial port, which only --backend dynamixel opens" in (
        capsys.readouterr().err
    )
    out = tmp_path / "demo"
    assert main(["demo", "--out-dir", str(out), "--keypoint-model", "agnostic2d"]) != 0
    assert "add --input 2d" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--max-frames", "0"], "--max-frames must be at least 1, got 0"),
        (["--fps", "inf"], "--fps must be a frame rate, 1–1000 frames per second, got inf"),
        (["--fps", "1e9"], "--fps must be a frame rate, 1–1000 frames per second, got 1e+09"),
        (["--keypoint-fps", "nan"], "--keypoint-fps must be a frame rate, 1–1000 frames"),
    ],
)
def test_convert_refuses_bad_numbers_before_any_clip(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], says: str
) -> None:
    assert main(["convert", str(WALK), "--out", str(tmp_path / "a.npz"), *extra]) != 0
    err = capsys.readouterr()
    assert says in err.err
    assert "summary" not in err.out  # refused before the clips, not per clip


def test_exporting_a_file_that_is_no_checkpoint_is_one_short_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["export", str(WALK), "--out", str(tmp_path / "m.npz")]) != 0
    err = capsys.readouterr().err.strip()
    assert "a BVH motion clip, not a model: name a model such as default, a .pt checkpoint" in err
    assert "\n" not in err
    assert len(err) < 400


def test_canonical_input_needs_a_skeleton_aware_model(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["convert", str(WALK), "--out", str(tmp_path / "a.npz"),
                 "--canonical-input"]) != 0  # fmt: skip
    assert "--canonical-input: for a skeleton-aware model" in capsys.readouterr().err
    assert not (tmp_path / "a.npz").exists()


@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--source", "udp://127.0.0.1:9", "--loop"], "--loop: the source"),
        (["--source", "udp://127.0.0.1:9", "--speed", "2"], "--speed: the source"),
        (["--source", "udp://127.0.0.1:9", "--keypoint-model", "agnostic2d"],
         "--keypoint-model: the source"),
        (["--source", f"replay:{WALK}", "--token", "x"], "--token: the source"),
        (["--source", "udp://127.0.0.1:9", "--insecure-no-token"], "without --allow-remote"),
        (["--source", f"replay:{WALK}", "--wake-on-input"], "--wake-on-input: the source"),
        (["--source", f"replay:{WALK}", "--fix-registers"],
         "--fix-registers writes the servos' registers, and --backend sim opens no servos"),
        (["--source", f"replay:{WALK}", "--view-port", "0", "--no-browser"],
         "--view-port, --no-browser: about the live page, which only --view serves"),
        (["--source", f"replay:{WALK}", "--view-host", "0.0.0.0"], "--view-host: about the live"),
    ],
)  # fmt: skip
def test_stream_refuses_options_its_source_ignores(
    capsys: pytest.CaptureFixture[str], extra: list[str], says: str
) -> None:
    assert main(["stream", "--backend", "sim", "--duration", "0.2", *extra]) != 0
    assert says in capsys.readouterr().err


def test_eval_robot_refuses_plots_it_cannot_write_before_any_clip(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a_file = tmp_path / "plots.png"
    a_file.write_bytes(b"")
    assert main(["eval-robot", "--plots", str(a_file), "--data", str(tmp_path / "none")]) == 1
    err = capsys.readouterr().err
    assert f"--plots {a_file}" in err
    assert "is a file, not a folder" in err
    with pytest.raises(SystemExit, match="--corrupt and --input 2d reports have no plots"):
        main(["eval-robot", "--plots", str(tmp_path), "--corrupt", "jitter"])


@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--source", "2d", "--positions"], "--positions times the 3D position packets"),
        (["--keypoint-model", "agnostic2d"], "--keypoint-model is about --source 2d's"),
    ],
)
def test_bench_pipeline_refuses_options_its_source_ignores(
    capsys: pytest.CaptureFixture[str], extra: list[str], says: str
) -> None:
    assert main(["bench", "pipeline", "--frames", "5", "--warmup", "0", *extra]) == 1
    assert says in capsys.readouterr().err

"""The keypoint file readers, on fixtures written from each format's published specification
(tests/fixtures/keypoints: OpenPose doc/02_output.md BODY_25 and COCO-18 orders, MediaPipe's
33-landmark pose model card, COCO-17 in MMPose / YOLO-pose / COCO-annotation forms), and
malformed files whose errors name the file and the frame."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from robot_retarget.keypoints.coco17 import Coco
from robot_retarget.sources.keypoints import (
    KeypointFormatError,
    is_keypoint_input,
    load_keypoints,
)

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "keypoints"


def test_openpose_body25_maps_each_point_from_its_body25_index() -> None:
    seq = load_keypoints(FIXTURES / "openpose_body25")
    assert seq.num_frames == 3
    assert seq.fps == 30.0
    # Fixture: BODY_25 point i of the main person at x = 600 + f + 4 i, y = 300 + 10 i.
    body25 = {Coco.nose: 0, Coco.left_shoulder: 5, Coco.right_shoulder: 2, Coco.left_hip: 12,
              Coco.right_hip: 9, Coco.left_ankle: 14, Coco.right_eye: 15,
              Coco.left_ear: 18}  # fmt: skip
    for coco, i in body25.items():
        assert seq.xy[0, coco].tolist() == [600 + 4 * i, 300 + 10 * i]
        assert seq.xy[2, coco, 0] == 602 + 4 * i
    # BODY_25 point 4 (RWrist) has confidence 0.1 < 0.3: marked missing, not used.
    assert not seq.valid[:, Coco.right_wrist].any()
    assert np.isnan(seq.xy[:, Coco.right_wrist]).all()
    assert seq.valid[:, Coco.left_wrist].all()


def test_openpose_follows_the_larger_person() -> None:
    seq = load_keypoints(FIXTURES / "openpose_body25")
    # The small person (listed first) has x < 200; the larger one is followed in every frame.
    assert np.nanmin(seq.xy[..., 0]) >= 600


def test_openpose_coco18_layout() -> None:
    seq = load_keypoints(FIXTURES / "openpose_coco18")
    coco18 = {Coco.left_hip: 11, Coco.right_hip: 8, Coco.left_ankle: 13, Coco.right_eye: 14}
    for coco, i in coco18.items():
        assert seq.xy[0, coco].tolist() == [500 + 4 * i, 200 + 10 * i]
    # COCO-18 point 16 (REar) written as 0, 0, 0: missing.
    assert not seq.valid[:, Coco.right_ear].any()


def test_mediapipe_landmarks_in_pixels() -> None:
    seq = load_keypoints(FIXTURES / "mediapipe_pose.json")
    assert seq.fps == 25.0
    assert seq.num_frames == 3
    assert seq.image_size == (1000.0, 500.0)  # the stream's camera takes its centre
    mp = {Coco.nose: 0, Coco.left_eye: 2, Coco.right_ear: 8, Coco.left_shoulder: 11,
          Coco.right_hip: 24, Coco.left_ankle: 27}  # fmt: skip
    for coco, i in mp.items():
        np.testing.assert_allclose(seq.xy[0, coco], [100 + 10 * i, 50 + 5 * i])
    assert not seq.valid[:, Coco.right_wrist].any()  # visibility 0.2
    assert not seq.valid[2].any()  # nobody in the third frame: all missing


def test_coco17_jsonl_all_three_person_forms() -> None:
    seq = load_keypoints(FIXTURES / "coco17.jsonl")
    assert seq.num_frames == 3
    assert seq.fps == 30.0
    for f in range(3):
        np.testing.assert_allclose(seq.xy[f, Coco.right_shoulder], [300 + 7 * 6 + f, 220])
    assert not seq.valid[0, Coco.left_wrist]  # score 0.05 on the first line
    assert seq.valid[1:, Coco.left_wrist].all()


def test_detection_by_path(tmp_path: Path) -> None:
    assert is_keypoint_input(FIXTURES / "openpose_body25")
    assert is_keypoint_input(FIXTURES / "coco17.jsonl")
    assert is_keypoint_input(FIXTURES / "mediapipe_pose.json")
    (tmp_path / "a.bvh").write_text("HIERARCHY\n")
    assert not is_keypoint_input(tmp_path)


def _copy(name: str, tmp_path: Path) -> Path:
    dst = tmp_path / name
    if (FIXTURES / name).is_dir():
        shutil.copytree(FIXTURES / name, dst)
    else:
        shutil.copy(FIXTURES / name, dst)
    return dst


def test_openpose_broken_frame_names_file_and_frame(tmp_path: Path) -> None:
    folder = _copy("openpose_body25", tmp_path)
    bad = folder / "video_000000000001_keypoints.json"
    bad.write_text('{"version": 1.3, "people": [')
    with pytest.raises(KeypointFormatError) as info:
        load_keypoints(folder)
    assert info.value.frame == 1
    assert info.value.path == str(bad)
    assert "frame 1" in str(info.value)
    assert bad.name in str(info.value)


def test_openpose_wrong_point_count(tmp_path: Path) -> None:
    folder = _copy("openpose_coco18", tmp_path)
    bad = folder / "video_000000000000_keypoints.json"
    bad.write_text(json.dumps({"version": 1.3, "people": [{"pose_keypoints_2d": [1.0] * 60}]}))
    with pytest.raises(KeypointFormatError, match=r"frame 0: person 0: .*60 values.*BODY_25"):
        load_keypoints(folder)


def test_mediapipe_without_image_size(tmp_path: Path) -> None:
    path = _copy("mediapipe_pose.json", tmp_path)
    doc = json.loads(path.read_text())
    del doc["image_width"]
    doc["frames"][1]["pose_landmarks"][0] = doc["frames"][1]["pose_landmarks"][0][:30]
    path.write_text(json.dumps(doc))
    with pytest.raises(KeypointFormatError, match="'image_width' must be the image size"):
        load_keypoints(path)  # no image size: the landmarks cannot be put in pixels
    path.write_text(json.dumps({"people": []}))
    with pytest.raises(KeypointFormatError, match="expected MediaPipe landmarks"):
        load_keypoints(path)
    path.write_text('{"keypoints": []}\n{"keypoints": []}\n')
    with pytest.raises(KeypointFormatError, match=r"COCO-17 JSON lines .* a \.jsonl file"):
        load_keypoints(path)
    doc["image_width"] = 1000
    path.write_text(json.dumps(doc))
    with pytest.raises(KeypointFormatError, match=r"frame 1: person 0: expected 33 landmarks"):
        load_keypoints(path)


def test_mediapipe_bad_landmark(tmp_path: Path) -> None:
    path = _copy("mediapipe_pose.json", tmp_path)
    doc = json.loads(path.read_text())
    doc["frames"][0]["pose_landmarks"][0][5] = {"x": "left"}
    path.write_text(json.dumps(doc))
    with pytest.raises(KeypointFormatError) as info:
        load_keypoints(path)
    assert info.value.frame == 0
    assert "landmark 5" in str(info.value)


def test_coco_jsonl_malformed_line(tmp_path: Path) -> None:
    path = _copy("coco17.jsonl", tmp_path)
    lines = path.read_text().splitlines()
    obj = json.loads(lines[2])
    obj["people"][0]["keypoints"] = obj["people"][0]["keypoints"][:48]
    path.write_text("\n".join([lines[0], lines[1], json.dumps(obj)]) + "\n")
    with pytest.raises(KeypointFormatError) as info:
        load_keypoints(path)
    assert info.value.frame == 2
    assert path.name in str(info.value)
    assert "shape (48,)" in str(info.value)
    path.write_text(lines[0] + "\n{not json\n")
    bad_line = r"frame 1: not a JSON document \(Expecting .* at column 2\)"
    with pytest.raises(KeypointFormatError, match=bad_line):
        load_keypoints(path)


def test_pairs_without_scores_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "x.jsonl"
    path.write_text(json.dumps({"people": [{"keypoints": [[1, 2]] * 17}]}) + "\n")
    with pytest.raises(KeypointFormatError, match="keypoint_scores"):
        load_keypoints(path)


def test_values_that_parse_but_mean_nothing_are_named(tmp_path: Path) -> None:
    """Nested OpenPose triples, a MediaPipe 'presence' of null, and JSON's 1e999 (infinity) as
    an image size or a frame rate: each a one-line error naming the file and the field."""
    folder = _copy("openpose_body25", tmp_path)
    bad = folder / "video_000000000000_keypoints.json"
    bad.write_text(json.dumps({"people": [{"pose_keypoints_2d": [[1.0, 2.0, 0.9]] * 25}]}))
    with pytest.raises(KeypointFormatError, match=r"one flat list .* shape \(25, 3\)"):
        load_keypoints(folder)
    path = _copy("mediapipe_pose.json", tmp_path)
    doc = json.loads(path.read_text())
    doc["frames"][0]["pose_landmarks"][0][3]["presence"] = None
    path.write_text(json.dumps(doc))
    with pytest.raises(KeypointFormatError, match=r"landmark 3: .*'presence'"):
        load_keypoints(path)
    doc = json.loads((FIXTURES / "mediapipe_pose.json").read_text())
    path.write_text(json.dumps(doc).replace('"image_width": ', '"image_width": 1e999, "w": '))
    with pytest.raises(KeypointFormatError, match=r"'image_width' .* got inf"):
        load_keypoints(path)
    path.write_text(json.dumps({**doc, "fps": 1}).replace('"fps": 1', '"fps": 1e999'))
    with pytest.raises(KeypointFormatError, match=r"'fps' must be a camera frame rate.*, got inf"):
        load_keypoints(path)
    lines = (FIXTURES / "coco17.jsonl").read_text().splitlines()
    first = json.loads(lines[0])
    jsonl = tmp_path / "inf.jsonl"
    jsonl.write_text(json.dumps({**first, "fps": 1}).replace('"fps": 1', '"fps": 1e999') + "\n")
    with pytest.raises(KeypointFormatError, match="frame 0: 'fps' must be a camera frame rate"):
        load_keypoints(jsonl)


def test_openpose_frames_keep_their_time_by_the_numbers_in_their_names(tmp_path: Path) -> None:
    """A file OpenPose did not write is a frame nobody was seen in, and unpadded numbers go
    in number order (a missing file had moved every later frame one early, and 'clip_10_'
    came before 'clip_9_')."""
    folder = _copy("openpose_body25", tmp_path)
    (folder / "video_000000000001_keypoints.json").unlink()
    seq = load_keypoints(folder)
    assert seq.num_frames == 3
    assert not seq.valid[1].any()
    assert seq.xy[2, Coco.nose, 0] == 602  # frame 2's own points, at frame 2
    unpadded = tmp_path / "unpadded"
    unpadded.mkdir()
    for k in range(3):
        src = FIXTURES / "openpose_body25" / f"video_00000000000{k}_keypoints.json"
        shutil.copy(src, unpadded / f"clip_{k + 8}_keypoints.json")  # clip_8, clip_9, clip_10
    seq = load_keypoints(unpadded)
    assert seq.xy[:, Coco.nose, 0].tolist() == [600, 601, 602]


def test_coco_jsonl_frames_keep_their_time_and_errors_name_the_line(tmp_path: Path) -> None:
    """A line's 'frame' (else 't') places it: skipped frames are frames nobody was seen in
    (a jump from frame 1 to 4 was read as contiguous); errors name the file's line."""
    path = _copy("coco17.jsonl", tmp_path)
    lines = [json.loads(x) for x in path.read_text().splitlines()]
    for k, obj in enumerate(lines):
        obj.pop("t", None)
        obj["frame"] = [10, 11, 14][k]
    path.write_text("\n\n".join(json.dumps(x) for x in lines) + "\n")  # blank lines between
    seq = load_keypoints(path)
    assert seq.num_frames == 5
    assert seq.valid[[0, 1, 4]].any(axis=1).all()
    assert not seq.valid[[2, 3]].any()
    for k, obj in enumerate(lines):
        obj.pop("frame")
        obj["t"] = [0.0, 1 / 30, 3 / 30][k]
    path.write_text("\n".join(json.dumps(x) for x in lines) + "\n")
    assert load_keypoints(path).num_frames == 4
    lines[2]["t"] = 0.0
    path.write_text("\n".join(json.dumps(x) for x in lines) + "\n")
    with pytest.raises(KeypointFormatError, match="lines must come in time order") as info:
        load_keypoints(path)
    assert info.value.line == 3
    path.write_text(json.dumps(lines[0]) + "\n\n{not json\n")
    with pytest.raises(KeypointFormatError) as info:
        load_keypoints(path)
    assert info.value.line == 3  # the file's line, after a blank one
    assert "line 2" not in str(info.value).split("line 3")[1]


def test_an_openpose_folder_with_a_broken_first_file_is_still_openpose_s(tmp_path: Path) -> None:
    """Told by its files' names: the error names the file (it was taken for a folder of BVH
    clips, 'no .bvh files in this folder')."""
    folder = _copy("openpose_body25", tmp_path)
    first = folder / "video_000000000000_keypoints.json"
    first.write_text('{"version": 1.3}')
    assert is_keypoint_input(folder)
    with pytest.raises(
        KeypointFormatError, match="expected an object with a 'people' list"
    ) as info:
        load_keypoints(folder)
    assert info.value.path == str(first)

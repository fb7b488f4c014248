"""Output paths: every check before the work, atomic writes, the recording's fallback."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from robot_retarget.cli.output_paths import (
    Output,
    OutputPathError,
    StagedWrites,
    Writer,
    check_folder,
    check_outputs,
    fallback_folders,
    save_with_fallback,
    write_atomic,
)


def _text(content: str) -> Writer:
    def write(path: Path) -> None:
        path.write_text(content)

    return write


def _failing(path: Path) -> None:
    path.write_text("half a fil")
    raise OSError(28, "No space left on device")


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def test_wrong_suffix_is_refused(tmp_path: Path) -> None:
    with pytest.raises(OutputPathError, match=r"--out .*t\.txt: must end in \.npz, \.csv") as e:
        check_outputs([Output("--out", tmp_path / "t.txt", (".npz", ".csv"))])
    assert e.value.option == "--out"
    assert e.value.path == str(tmp_path / "t.txt")


def test_an_output_is_never_an_input(tmp_path: Path) -> None:
    clip = tmp_path / "walk.bvh"
    clip.write_text("HIERARCHY")
    link = tmp_path / "link.bvh"
    link.symlink_to(clip)
    hard = tmp_path / "hard.bvh"
    os.link(clip, hard)
    for out in (clip, tmp_path / "." / "walk.bvh", link, hard):
        with pytest.raises(OutputPathError, match="is the input") as e:
            check_outputs([Output("--bvh-out", out, (".bvh",))], inputs=[clip], force=True)
        assert e.value.other == str(clip)
        assert str(clip) in str(e.value)


def test_no_two_outputs_share_a_path(tmp_path: Path) -> None:
    a = Output("--out", tmp_path / "t.npz")
    b = Output("--bvh-out", tmp_path / "sub" / ".." / "t.npz")
    with pytest.raises(OutputPathError, match="also the output of --out") as e:
        check_outputs([a, b])
    assert e.value.option == "--bvh-out"
    assert e.value.other == str(a.path)


def test_existing_outputs_need_force(tmp_path: Path) -> None:
    outs = [Output("--out", tmp_path / f"{k}.npz") for k in range(3)]
    for o in outs[1:]:
        o.path.write_text("old")
    with pytest.raises(OutputPathError, match=r"already exists \(and 1 more output"):
        check_outputs(outs)
    check_outputs(outs, force=True)
    (tmp_path / "dir.npz").mkdir()
    with pytest.raises(OutputPathError, match="is a folder"):
        check_outputs([Output("--out", tmp_path / "dir.npz")], force=True)


def test_folders_must_exist_and_be_writable(tmp_path: Path, read_only_dir: Path) -> None:
    with pytest.raises(OutputPathError, match=r"no such folder; create it first \(mkdir -p"):
        check_outputs([Output("--record", tmp_path / "missing" / "r.npz")])
    with pytest.raises(OutputPathError, match=r"\(mkdir -p '.*/my out'\)"):  # pastes as one path
        check_outputs([Output("--out", tmp_path / "my out" / "r.npz")])
    with pytest.raises(OutputPathError, match="not writable"):
        check_outputs([Output("--record", read_only_dir / "r.npz")])
    # A folder output may be created, if its nearest existing parent is writable.
    check_outputs([Output("--out", tmp_path / "new" / "deep" / "r.npz", make_folders=True)])
    assert not (tmp_path / "new").exists()  # checked, not created
    with pytest.raises(OutputPathError, match=r"nearest existing parent .* not writable"):
        check_outputs([Output("--out", read_only_dir / "new" / "r.npz", make_folders=True)])
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputPathError, match="is a file, not a folder"):
        check_folder(tmp_path / "file", option="--out-dir", create=True)
    with pytest.raises(OutputPathError, match="is a file"):
        check_folder(tmp_path / "file" / "sub", option="--out-dir", create=True)
    assert _leftovers(tmp_path) == []  # the probes are gone


def test_write_atomic_leaves_no_partial_file(tmp_path: Path) -> None:
    out = tmp_path / "t.csv"
    with pytest.raises(OutputPathError, match="No space left"):
        write_atomic(out, _failing, option="--out")
    assert list(tmp_path.iterdir()) == []
    out.write_text("previous")
    with pytest.raises(OutputPathError):
        write_atomic(out, _failing, force=True)
    assert out.read_text() == "previous"  # the old file survives a failed replacement
    assert _leftovers(tmp_path) == []
    write_atomic(out, _text("new"), force=True)
    assert out.read_text() == "new"
    with pytest.raises(OutputPathError, match="--force"):
        write_atomic(out, _text("newer"))
    assert out.read_text() == "new"


def _group(a: Path, b: Path, second: Writer | None) -> None:
    """Stage a then b (None: crash between the two) and commit."""
    with StagedWrites(force=True) as stage:
        stage.write(a, _text("new a"))
        if second is None:
            raise RuntimeError("the preview renderer crashed")
        stage.write(b, second)


def test_a_group_is_written_all_or_nothing(tmp_path: Path) -> None:
    a, b = tmp_path / "a.npz", tmp_path / "b.gif"
    a.write_text("old a")
    with pytest.raises(OutputPathError):
        _group(a, b, _failing)
    assert a.read_text() == "old a"
    assert not b.exists()
    with pytest.raises(RuntimeError):
        _group(a, b, None)
    assert a.read_text() == "old a"
    assert _leftovers(tmp_path) == []
    _group(a, b, _text("b"))
    assert (a.read_text(), b.read_text()) == ("new a", "b")


def test_temporaries_a_writer_derives_are_removed(tmp_path: Path) -> None:
    def writes_a_part_file_then_fails(path: Path) -> None:
        path.with_name(path.name + ".part").write_text("partial")  # as RobotTrajectory.write
        raise ValueError("NaN in the trajectory")

    with pytest.raises(ValueError, match="NaN"):
        write_atomic(tmp_path / "t.npz", writes_a_part_file_then_fails)
    assert list(tmp_path.iterdir()) == []


def test_folders_are_created_only_when_asked(tmp_path: Path) -> None:
    with pytest.raises(OutputPathError, match="cannot write it"):
        write_atomic(tmp_path / "gone" / "t.csv", _text("x"))
    write_atomic(tmp_path / "made" / "t.csv", _text("x"), make_folders=True)
    assert (tmp_path / "made" / "t.csv").read_text() == "x"


def test_the_recording_goes_to_a_fallback_when_its_folder_is_gone(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    session = tmp_path / "session"
    session.mkdir()
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    check_outputs([Output("--record", session / "take.npz")])
    shutil.rmtree(session)  # e.g. the USB stick was pulled during the session
    warnings: list[str] = []
    written = save_with_fallback(
        session / "take.npz", _text("42 commands"), option="--record", warn=warnings.append
    )
    assert written.parent == work
    assert written.name.startswith("take-")
    assert written.suffix == ".npz"
    assert written.read_text() == "42 commands"
    assert len(warnings) == 1
    assert str(written) in warnings[0]
    assert "--record" in warnings[0]


def test_the_recording_is_never_replaced_without_force(tmp_path: Path) -> None:
    out = tmp_path / "take.csv"
    out.write_text("an earlier take")  # appeared while the session ran
    warnings: list[str] = []
    written = save_with_fallback(out, _text("this take"), warn=warnings.append)
    assert out.read_text() == "an earlier take"
    assert written != out
    assert written.parent == tmp_path
    assert written.read_text() == "this take"
    assert warnings


def test_fallback_folders_are_distinct(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    folders = fallback_folders(tmp_path / "x.npz")
    assert folders[0] == tmp_path
    assert len(folders) == len({f.resolve() for f in folders})


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux's /proc")
def test_a_virtual_file_system_is_named_as_such() -> None:
    """/proc exists, yet creating a file in it fails with "No such file or directory": the
    message had said just that of a folder that is there."""
    with pytest.raises(OutputPathError, match="virtual file system"):
        check_outputs([Output("--out", Path("/proc/x.npz"))])

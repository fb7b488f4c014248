from __future__ import annotations

from pathlib import Path

import pytest

from robot_retarget.errors import SourceError
from robot_retarget.sources import ReplaySource, UdpSource, open_source
from robot_retarget.sources.tcp_bvh import TcpBvhSource

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "motion"


def test_replay_spec() -> None:
    src = open_source(f"replay:{FIXTURES / 'tiny_walk.bvh'}", loop=True, speed=2.0)
    assert isinstance(src, ReplaySource)
    assert src.loop
    assert src.speed == 2.0


def test_udp_spec_defaults() -> None:
    src = open_source("udp://127.0.0.1:9751", token="t")
    assert isinstance(src, UdpSource)
    assert (src.host, src.port, src.token) == ("127.0.0.1", 9751, "t")
    assert isinstance(open_source("udp://"), UdpSource)
    assert src.cleans_positions
    assert not open_source("udp://127.0.0.1:0", clean_positions=False).cleans_positions


def test_tcp_bvh_spec() -> None:
    src = open_source("tcp-bvh://127.0.0.1:7001")
    assert isinstance(src, TcpBvhSource)
    assert src.port == 7001


@pytest.mark.parametrize(
    ("spec", "match"),
    [
        ("replay:/no/such/clip.bvh", "does not exist"),
        (
            "replay:",
            "replay: names no clip; give replay:PATH/TO/CLIP.bvh",
        ),  # was "clip . is a folder"
        ("udp://0.0.0.0:9750", "allow-remote"),
        ("tcp-bvh://127.0.0.1", "needs a port"),
        ("udp://127.0.0.1:notaport", "bad port"),
        ("rtsp://camera", "unknown source"),
    ],
)
def test_bad_specs(spec: str, match: str) -> None:
    with pytest.raises(SourceError, match=match):
        open_source(spec)


def test_replay_folder_says_folder(tmp_path: Path) -> None:
    # a folder exists, so "does not exist" would send the user looking for a typo
    with pytest.raises(SourceError, match="is a folder; replay takes one clip") as info:
        open_source(f"replay:{tmp_path}")
    assert "does not exist" not in str(info.value)


def test_unreadable_replay_clip(tmp_path: Path) -> None:
    bad = tmp_path / "bad.bvh"
    bad.write_text("not a bvh")
    with pytest.raises(SourceError, match="cannot replay"):
        open_source(f"replay:{bad}")

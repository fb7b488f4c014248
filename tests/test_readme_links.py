"""The README's in-page links (its contents list among them) point at headings that exist,
with GitHub's anchor rules: lower case, punctuation dropped, spaces as hyphens, a repeated
heading numbered from -1."""

from __future__ import annotations

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def _anchors(text: str) -> set[str]:
    seen: dict[str, int] = {}
    out: set[str] = set()
    in_code = False
    for line in text.splitlines():
        if line.startswith("```"):
            in_code = not in_code
        m = None if in_code else re.match(r"^#{1,6} (.+)$", line)
        if m is None:
            continue
        anchor = re.sub(r"[^\w\- ]", "", m.group(1).strip().lower()).replace(" ", "-")
        count = seen.get(anchor, 0)
        seen[anchor] = count + 1
        out.add(f"{anchor}-{count}" if count else anchor)
    return out


def test_anchor_rules() -> None:
    text = "# A b\n## Video input: 2D keypoints\n## The planes in `stream`\n## A b\n"
    assert _anchors(text) == {"a-b", "video-input-2d-keypoints", "the-planes-in-stream", "a-b-1"}


def test_every_in_page_link_has_its_heading() -> None:
    text = README.read_text(encoding="utf-8")
    links = re.findall(r"\]\(#([^)]+)\)", text)
    assert len(links) >= 10  # the contents list
    missing = sorted(set(links) - _anchors(text))
    assert not missing, f"README links to headings that do not exist: {missing}"

"""Named blocks of a flat CasADi vector: which slice of ``p`` (or ``g``) holds what.

A window of W frames lays its vector out as ``[shared blocks | frame 0 | … | frame W−1]``: the
shared blocks first, so that every slice is the same whatever the window length (the online
problem, W = 1, and the offline windows share one layout). Each frame block has the same
named entries. The layout is generated once from the entries' declarations (the cost terms'
parameters, see :mod:`.objective`); the NLP builder and the Retargeter's writers both read
their offsets from it, so nobody counts offsets by hand.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class Parameter:
    """One named block: ``size`` entries, per frame or once for the whole window (shared)."""

    name: str
    size: int
    shared: bool = False


class ParameterLayout:
    """Names → slices of a vector laid out as ``[shared | frame 0 | … | frame W−1]``."""

    def __init__(self, blocks: Sequence[Parameter]) -> None:
        self._shared: dict[str, slice] = {}
        self._frame: dict[str, slice] = {}
        shared_size = frame_size = 0
        for b in blocks:
            if b.size < 0:
                raise ValueError(f"parameter {b.name!r} has negative size {b.size}")
            if b.name in self._shared or b.name in self._frame:
                raise ValueError(f"parameter {b.name!r} is declared twice")
            if b.shared:
                self._shared[b.name] = slice(shared_size, shared_size + b.size)
                shared_size += b.size
            else:
                self._frame[b.name] = slice(frame_size, frame_size + b.size)
                frame_size += b.size
        self.blocks = tuple(blocks)
        self.shared_size = shared_size
        self.frame_size = frame_size

    def size(self, window: int) -> int:
        """Length of the whole vector for ``window`` frames."""
        return self.shared_size + window * self.frame_size

    def shared(self, name: str) -> slice:
        """Absolute slice of a shared block."""
        return self._shared[name]

    def frame(self, t: int, name: str) -> slice:
        """Absolute slice of a per-frame block in frame ``t``."""
        rel = self._frame[name]
        o = self.shared_size + t * self.frame_size
        return slice(o + rel.start, o + rel.stop)

    def slices(self, t: int, names: Sequence[str]) -> dict[str, slice]:
        """``{name: absolute slice}`` for ``names``: shared blocks, and frame ``t``'s blocks."""
        return {n: self._shared[n] if n in self._shared else self.frame(t, n) for n in names}

"""The precomputed network step plays its frames back in order, from the start after a reset,
and refuses a frame it was not given."""

from __future__ import annotations

import numpy as np
import pytest

from robot_retarget.pipeline.precomputed_step import PrecomputedStep


def test_frames_in_order_and_again_after_reset() -> None:
    quats = np.random.default_rng(0).normal(size=(3, 22, 4))
    root = np.arange(9.0).reshape(3, 3)
    step = PrecomputedStep(quats, root)
    ignored = (np.zeros((22, 4)), np.zeros(3))
    for _ in range(2):
        for t in range(3):
            q, r = step.step(*ignored)
            np.testing.assert_array_equal(q, quats[t])
            np.testing.assert_array_equal(r, root[t])
        with pytest.raises(ValueError, match="run on 3 frames; frame 3 was asked for"):
            step.step(*ignored)
        step.reset()


def test_mismatched_shapes_are_refused() -> None:
    with pytest.raises(ValueError, match="need quats"):
        PrecomputedStep(np.zeros((3, 22, 4)), np.zeros((2, 3)))

"""Standardizer: fitted statistics, identity start, round trip."""

from __future__ import annotations

import pytest
import torch

from robot_retarget.nn.models.normalization import Standardizer


def test_identity_until_fitted() -> None:
    s = Standardizer(3)
    x = torch.randn(4, 3)
    torch.testing.assert_close(s(x), x)


def test_fit_and_inverse() -> None:
    s = Standardizer(3)
    data = torch.randn(100, 3) * torch.tensor([2.0, 0.5, 0.0]) + torch.tensor([1.0, -1.0, 3.0])
    s.fit(data)
    z = s(data)
    torch.testing.assert_close(z[:, :2].mean(0), torch.zeros(2), atol=1e-5, rtol=0)
    torch.testing.assert_close(z[:, :2].std(0, unbiased=False), torch.ones(2), atol=1e-4, rtol=0)
    assert float(s.std[2]) == 1.0  # a constant feature is centred, not blown up
    torch.testing.assert_close(s.inverse(z), data, atol=1e-5, rtol=0)
    assert set(s.state_dict()) == {"mean", "std"}


def test_fit_checks_width() -> None:
    with pytest.raises(ValueError, match="last axis of 3"):
        Standardizer(3).fit(torch.zeros(5, 4))

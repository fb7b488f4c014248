"""Skeleton-aware networks (Aberman et al. 2020, "Skeleton-Aware Networks for Deep Motion
Retargeting"): one encoder per skeleton topology into a latent space on the primal skeleton,
one decoder out of it.

Each *domain* is a skeleton topology (robot_retarget.skeleton.armatures): the canonical
22-joint skeleton (what live sources send and what the optimizer consumes: a robot is a
canonical skeleton with its own proportions) and every BVH skeleton of the training data read
as it is, e.g. CMU's 31-joint MotionBuilder skeleton and its 43-joint DAZ conversion
(robot_retarget.motion.native_pose). Per domain:

- a static encoder: the rest offsets (divided by the skeleton's height) through skeletal
  linear layers and pooling, giving static features at every level;
- a dynamic encoder: per armature its joint's rotation (the root armature: the heading-free
  root rotation and the root movement), tiled with the level's static features, through
  skeleto-temporal convolution + leaky ReLU + skeletal pooling, twice, down to the primal
  skeleton (the root armature + one armature per chain).

One decoder writes the canonical skeleton for any target proportions: unpooling + skeletal
convolution with the target's static features, twice, to a rotation per canonical joint and
the root movement (in heights per frame, scaled by the target's height). Retargeting A → B is
decoder(encoder_A(motion), static(B)).

Ours, against the paper:

- the convolutions keep the frame rate (stride 1, no temporal down/up-sampling) and are causal
  by default (left padding), so the model streams frame by frame; ``causal=False`` centres the
  kernels (clips only);
- only the canonical skeleton has a decoder: nothing downstream consumes another topology;
- the root armature takes the canonical motion's root (its up axis, units and heading), for
  native sources too (see native_pose.py).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from torch import nn
from torch.nn import functional as nnf

from robot_retarget.nn.features import (
    FrameFeatures,
    MotionFeatures,
    compute_features,
    skeleton_height,
)
from robot_retarget.nn.models.base import Prediction, RetargetModel, RetargetOutput
from robot_retarget.nn.models.normalization import Standardizer
from robot_retarget.nn.models.weight_export import to_numpy
from robot_retarget.nn.skeletal_ops import SkeletalConv, SkeletalPool, SkeletalUnpool
from robot_retarget.skeleton.armatures import (
    ArmatureTopology,
    canonical_topology,
    check_homeomorphic,
)
from robot_retarget.skeleton.canonical import CANONICAL_JOINTS

if TYPE_CHECKING:
    from robot_retarget.runtime.model import RuntimeModel
    from robot_retarget.runtime.san import SANWeights

Tensor = torch.Tensor

CANONICAL_DOMAIN = "canonical"
CANONICAL_TOPOLOGY = canonical_topology()
POOL_STEPS = 2
ROOT_CHANNELS = 8  # heading-free root rotation (4) + root movement (4)
QUAT = 4
_SLOPE = 0.2  # leaky ReLU, as the paper


class StaticEncoder(nn.Module):
    """Offsets / height (B, A − 1, 3) → static features (B, A_l, S) at levels 0 … POOL_STEPS−1."""

    def __init__(self, topology: ArmatureTopology, channels: int, distance: int) -> None:
        super().__init__()
        levels = topology.levels(POOL_STEPS)
        pooling = topology.pooling(POOL_STEPS)
        self.linears = nn.ModuleList()
        self.pools = nn.ModuleList()  # pools[l]: level l → l + 1
        width = 3
        for lvl in range(POOL_STEPS):
            size = levels[lvl].size
            self.linears.append(
                SkeletalConv(
                    levels[lvl], [width] * size, [channels] * size, kernel_size=1, distance=distance
                )
            )
            if lvl + 1 < POOL_STEPS:
                self.pools.append(SkeletalPool(pooling[lvl], size))
            width = channels

    def forward(self, offsets: Tensor) -> list[Tensor]:
        b = offsets.shape[0]
        x = torch.cat([offsets.new_zeros(b, 1, 3), offsets], dim=1)[..., None]  # (B, A, 3, 1)
        out: list[Tensor] = []
        for lvl, linear in enumerate(self.linears):
            if lvl > 0:
                x = self.pools[lvl - 1](x)
            y = nnf.leaky_relu(linear(x), _SLOPE)  # (B, A·S, 1)
            x = y.view(b, x.shape[1], -1, 1)
            out.append(x[..., 0])
        return out


def _tile(static: Tensor, frames: int) -> Tensor:
    """(B, A, S) → (B, A, S, T)."""
    return static[..., None].expand(-1, -1, -1, frames)


class DynamicEncoder(nn.Module):
    """Root (B, T, 8) and armature rotations (B, T, A − 1, 4) → latent (B, A_primal, C, T)."""

    def __init__(
        self,
        topology: ArmatureTopology,
        channels: Sequence[int],
        static_channels: int,
        kernel_size: int,
        distance: int,
        causal: bool,
    ) -> None:
        super().__init__()
        levels = topology.levels(POOL_STEPS)
        pooling = topology.pooling(POOL_STEPS)
        s = static_channels
        self.channels = tuple(channels)
        self.convs = nn.ModuleList()
        self.pools = nn.ModuleList()
        for lvl in range(POOL_STEPS):
            size = levels[lvl].size
            if lvl == 0:
                widths = [ROOT_CHANNELS + s] + [QUAT + s] * (size - 1)
            else:
                widths = [channels[lvl - 1] + s] * size
            self.convs.append(
                SkeletalConv(
                    levels[lvl],
                    widths,
                    [channels[lvl]] * size,
                    kernel_size=kernel_size,
                    distance=distance,
                    causal=causal,
                )
            )
            self.pools.append(SkeletalPool(pooling[lvl], size))

    def forward(self, root: Tensor, quats: Tensor, static: Sequence[Tensor]) -> Tensor:
        b, t = root.shape[:2]
        s0 = _tile(static[0], t)
        root_block = torch.cat([root.transpose(1, 2), s0[:, 0]], dim=1)  # (B, 8 + S, T)
        rest = torch.cat([quats.permute(0, 2, 3, 1), s0[:, 1:]], dim=2)  # (B, A−1, 4 + S, T)
        x = torch.cat([root_block, rest.flatten(1, 2)], dim=1)
        for lvl, (conv, pool) in enumerate(zip(self.convs, self.pools, strict=True)):
            if lvl > 0:
                x = torch.cat([x, _tile(static[lvl], t)], dim=2)
            y = nnf.leaky_relu(conv(x), _SLOPE)
            x = pool(y.view(b, -1, self.channels[lvl], t))
        return x


class CanonicalDecoder(nn.Module):
    """Latent (B, A_primal, C, T) + target static features → root (B, T, 8) and rotations
    (B, T, A − 1, 4) of the canonical armatures (raw, not yet unit)."""

    def __init__(
        self,
        channels: Sequence[int],
        static_channels: int,
        kernel_size: int,
        distance: int,
        causal: bool,
    ) -> None:
        super().__init__()
        topology = CANONICAL_TOPOLOGY
        levels = topology.levels(POOL_STEPS)
        pooling = topology.pooling(POOL_STEPS)
        s = static_channels
        self.channels = tuple(channels)
        self.unpools = nn.ModuleList()
        self.convs = nn.ModuleList()
        for lvl in reversed(range(POOL_STEPS)):
            size = levels[lvl].size
            self.unpools.append(SkeletalUnpool(pooling[lvl], size))
            out = [channels[lvl - 1]] * size if lvl > 0 else [ROOT_CHANNELS] + [QUAT] * (size - 1)
            self.convs.append(
                SkeletalConv(
                    levels[lvl],
                    [channels[lvl] + s] * size,
                    out,
                    kernel_size=kernel_size,
                    distance=distance,
                    causal=causal,
                )
            )

    def forward(self, latent: Tensor, static: Sequence[Tensor]) -> tuple[Tensor, Tensor]:
        b, t = latent.shape[0], latent.shape[-1]
        x = latent
        y = latent.new_zeros(0)
        for i, (unpool, conv) in enumerate(zip(self.unpools, self.convs, strict=True)):
            lvl = POOL_STEPS - 1 - i
            x = torch.cat([unpool(x), _tile(static[lvl], t)], dim=2)
            y = conv(x)
            if lvl > 0:
                x = nnf.leaky_relu(y, _SLOPE).view(b, -1, self.channels[lvl - 1], t)
        root = y[:, :ROOT_CHANNELS].transpose(1, 2)
        quats = y[:, ROOT_CHANNELS:].view(b, -1, QUAT, t).permute(0, 3, 1, 2)
        return root, quats


class SAN(RetargetModel):
    """Skeleton-aware retargeting network (see the module docstring).

    ``domains`` maps a domain name to a topology spec (ArmatureTopology.spec) of a source
    skeleton besides the canonical one, which is always there; ``channels`` are the latent
    widths per armature after each encoder level (the paper doubles them per level),
    ``static_channels`` the static features' width, ``kernel_size`` the temporal kernel,
    ``distance`` the skeletal neighbourhood.
    """

    name = "san"

    def __init__(
        self,
        domains: Mapping[str, Mapping[str, Any]] | None = None,
        channels: Sequence[int] = (16, 32),
        static_channels: int = 8,
        kernel_size: int = 7,
        distance: int = 2,
        causal: bool = True,
    ) -> None:
        super().__init__()
        if len(channels) != POOL_STEPS:
            raise ValueError(f"channels needs {POOL_STEPS} widths, got {list(channels)}")
        self.channels = tuple(int(c) for c in channels)
        self.static_channels = static_channels
        self.kernel_size = kernel_size
        self.distance = distance
        self.causal = causal
        self.domain_specs: dict[str, dict[str, Any]] = {
            name: dict(spec) for name, spec in (domains or {}).items() if name != CANONICAL_DOMAIN
        }
        topologies = [CANONICAL_TOPOLOGY] + [
            ArmatureTopology.from_spec({**spec, "name": name})
            for name, spec in self.domain_specs.items()
        ]
        check_homeomorphic(topologies)
        self.topologies: dict[str, ArmatureTopology] = {t.name: t for t in topologies}
        self.domain_names = tuple(self.topologies)
        self.static_encoders = nn.ModuleList(
            StaticEncoder(t, static_channels, distance) for t in topologies
        )
        self.encoders = nn.ModuleList(
            DynamicEncoder(t, self.channels, static_channels, kernel_size, distance, causal)
            for t in topologies
        )
        self.decoder = CanonicalDecoder(
            self.channels, static_channels, kernel_size, distance, causal
        )
        self.root_norm = Standardizer(4)
        self._canon_index = torch.tensor(CANONICAL_TOPOLOGY.joints[1:])
        self._window: list[tuple[Tensor, Tensor]] = []

    # --- configuration ---------------------------------------------------------------------

    def config(self) -> dict[str, Any]:
        return {
            "domains": self.domain_specs,
            "channels": list(self.channels),
            "static_channels": self.static_channels,
            "kernel_size": self.kernel_size,
            "distance": self.distance,
            "causal": self.causal,
        }

    @property
    def receptive_field(self) -> int:
        """Frames one output frame depends on (4 convolutions of ``kernel_size``)."""
        return 2 * POOL_STEPS * (self.kernel_size - 1) + 1

    def domain_of(self, topology: ArmatureTopology) -> str | None:
        """The name of the domain with ``topology``'s structure, or None."""
        for name, t in self.topologies.items():
            if t.same_structure(topology):
                return name
        return None

    def fit_normalization(self, features: MotionFeatures, offsets: Tensor) -> None:
        self.root_norm.fit(_scaled_root_vel(features.root_vel, skeleton_height(offsets)))

    # --- encoding and decoding -------------------------------------------------------------

    def _index(self, domain: str) -> int:
        try:
            return self.domain_names.index(domain)
        except ValueError:
            raise ValueError(
                f"SAN has no encoder for skeleton {domain!r}; it knows {list(self.domain_names)}"
            ) from None

    def encode(
        self,
        domain: str,
        root_quat: Tensor,
        root_vel: Tensor,
        height: Tensor,
        quats: Tensor,
        offsets: Tensor,
    ) -> Tensor:
        """Latent (B, A_primal, C, T) of a motion on ``domain``'s skeleton: heading-free root
        rotation (B, T, 4), root movement (B, T, 4), the skeleton's height (B,), armature
        rotations (B, T, A − 1, 4) and offsets (B, A − 1, 3) in metres."""
        i = self._index(domain)
        static = self.static_encoders[i](offsets / height[:, None, None])
        root = torch.cat([root_quat, self.root_norm(_scaled_root_vel(root_vel, height))], dim=-1)
        latent: Tensor = self.encoders[i](root, quats, static)
        return latent

    def encode_canonical(self, src: MotionFeatures, src_offsets: Tensor) -> Tensor:
        idx = self._canon_index.to(src_offsets.device)
        return self.encode(
            CANONICAL_DOMAIN,
            src.local_quats[:, :, 0],
            src.root_vel,
            skeleton_height(src_offsets),
            src.local_quats[:, :, idx],
            src_offsets[:, idx],
        )

    def decode(self, latent: Tensor, tgt_offsets: Tensor) -> Prediction:
        """Heading-free canonical rotations and root movement for ``tgt_offsets`` (B, 22, 3)."""
        idx = self._canon_index.to(tgt_offsets.device)
        height = skeleton_height(tgt_offsets)
        static = self.static_encoders[0](tgt_offsets[:, idx] / height[:, None, None])
        root, rest = self.decoder(latent, static)
        b, t = root.shape[:2]
        quats = rest.new_zeros(b, t, len(CANONICAL_JOINTS), QUAT)
        quats = quats.index_copy(2, idx, rest)
        quats[:, :, 0] = root[..., :QUAT]
        quats = quats / torch.linalg.vector_norm(quats, dim=-1, keepdim=True).clamp_min(1e-6)
        vel = _unscaled_root_vel(self.root_norm.inverse(root[..., QUAT:]), height)
        return Prediction(local_quats=quats, root_vel=vel)

    def forward_native(
        self,
        domain: str,
        src_local_quats: Tensor,
        src_root_pos: Tensor,
        src_offsets: Tensor,
        native_quats: Tensor,
        native_offsets: Tensor,
        tgt_offsets: Tensor,
    ) -> RetargetOutput:
        """Retarget clips read on their own skeleton: as ``forward`` (whose canonical inputs
        give the root armature), the joints from ``native_quats`` (B, T, A − 1, 4) and
        ``native_offsets`` (B, A − 1, 3) of ``domain``'s topology."""
        q, root, src_off, nq, n_off, tgt = self._cast(
            src_local_quats, src_root_pos, src_offsets, native_quats, native_offsets, tgt_offsets
        )
        src = compute_features(q, root, src_off, self.parents)
        latent = self.encode(
            domain, src.local_quats[:, :, 0], src.root_vel, skeleton_height(src_off), nq, n_off
        )
        return self.output(self.decode(latent, tgt), root[:, 0], src.yaw[:, 0], tgt)

    # --- the live path ------------------------------------------------------------------

    def runtime(self) -> RuntimeModel | None:
        """The numpy step of the canonical path (the live path); None for a non-causal SAN."""
        if not self.causal:
            return None
        from robot_retarget.runtime.model import RuntimeModel

        return RuntimeModel(name=self.name, architecture="san", weights=self.export_weights())

    @torch.no_grad()
    def export_weights(self) -> SANWeights:
        """The canonical encoder, its static encoder and the decoder as dense numpy arrays."""
        from robot_retarget.runtime.san import SANWeights

        def conv(layer: object) -> tuple[Any, Any]:
            assert isinstance(layer, SkeletalConv)
            return to_numpy(layer.dense_weight()), to_numpy(layer.bias)

        def pool(layer: object) -> Any:
            assert isinstance(layer, SkeletalPool)
            return to_numpy(layer.matrix)

        static = self.static_encoders[0]
        encoder = self.encoders[0]
        assert isinstance(static, StaticEncoder)
        assert isinstance(encoder, DynamicEncoder)
        return SANWeights(
            armature_joints=np.array(CANONICAL_TOPOLOGY.joints[1:], dtype=np.float64),
            pools=(pool(encoder.pools[0]), pool(encoder.pools[1])),
            static=(conv(static.linears[0]), conv(static.linears[1])),
            encoder=(conv(encoder.convs[0]), conv(encoder.convs[1])),
            decoder=(conv(self.decoder.convs[0]), conv(self.decoder.convs[1])),
            root_mean=to_numpy(self.root_norm.mean),
            root_std=to_numpy(self.root_norm.std),
            shape=(float(self.static_channels), float(self.causal)),
        )

    # --- the RetargetModel interface (canonical sources) -----------------------------------

    def retarget(self, src: MotionFeatures, src_offsets: Tensor, tgt_offsets: Tensor) -> Prediction:
        return self.decode(self.encode_canonical(src, src_offsets), tgt_offsets)

    def reset_state(self) -> None:
        self._window = []

    def step_features(
        self, src: FrameFeatures, src_offsets: Tensor, tgt_offsets: Tensor
    ) -> tuple[Tensor, Tensor]:
        """One frame: the clip network on the last ``receptive_field`` frames (the first frame
        repeated before the stream has that many, as the clip's padding), its last output. For
        causal convolutions this equals the clip path frame for frame."""
        if not self.causal:
            raise ValueError(
                "this SAN is non-causal (each frame needs future frames) and has no online "
                "step: score it with eval, or train one with --model-config causal=true (the "
                "default) to stream or convert"
            )
        frame = (src.local_quats, src.root_vel)
        if not self._window:
            self._window = [frame] * self.receptive_field
        self._window = [*self._window[1:], frame]
        quats = torch.stack([f[0] for f in self._window], dim=1)
        vel = torch.stack([f[1] for f in self._window], dim=1)
        feats = MotionFeatures(
            local_pos=quats.new_zeros(*quats.shape[:3], 3),
            root_vel=vel,
            local_quats=quats,
            yaw=vel.new_zeros(vel.shape[:2]),
        )
        pred = self.retarget(feats, src_offsets, tgt_offsets)
        return pred.local_quats[:, -1], pred.root_vel[:, -1]


def _scaled_root_vel(root_vel: Tensor, height: Tensor) -> Tensor:
    """Root movement in heights per frame (the turning rate unscaled)."""
    return torch.cat([root_vel[..., :3] / height[:, None, None], root_vel[..., 3:]], dim=-1)


def _unscaled_root_vel(scaled: Tensor, height: Tensor) -> Tensor:
    return torch.cat([scaled[..., :3] * height[:, None, None], scaled[..., 3:]], dim=-1)

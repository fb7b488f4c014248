"""Per-frame jitter of a live position sender, filtered as strongly as the stream shows it.

A pose estimator (or a mocap system with marker noise) adds jitter that is nearly independent
from frame to frame: centimetres at the wrists and ankles. A fixed low-pass filter (``stream
--one-euro``) trades it for lag, and the lag costs the robot on every clean stream too. Here
each bone's direction (and the root's position) runs a constant-velocity Kalman filter whose
measurement noise is *estimated from the stream itself*: the jitter's variance is read off the
second differences of the values as sent (white noise of σ gives second differences of variance
6σ²; a smooth motion sampled at 120 fps gives a tiny fraction of that), as a running median over
the last :data:`NOISE_WINDOW` frames, so the rare large accelerations of real motion do not
count as noise. On a clean stream the estimated noise is tiny, the Kalman gain is close to 1 and
frames all but pass through; on a jittery one the filter smooths, as much as the process noise
(the motion's assumed random acceleration) allows.

Directions, not positions, because directions are what the live path solves for: a bone's
length noise (the ``bone_length`` kind) changes no direction and passes untouched, where
filtering each joint's position on its own would turn it into direction noise. The frame is
rebuilt root outward from the filtered directions and the bone lengths as sent.

Stateful per stream: :meth:`JitterFilter.reset` at a sender restart. Frames must come in time
order (the caller restarts the stream when time goes back).
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np
import numpy.typing as npt

from robot_retarget.array_types import FloatArray
from robot_retarget.casadi_jit import CompiledFunction, compile_graph, memoized_graph
from robot_retarget.skeleton.tree_tables import validated_parents

ROOT_PROCESS_NOISE = 3.0
"""White acceleration density (m²/s³) of the root position's constant-velocity model."""

DIRECTION_PROCESS_NOISE = 100.0
"""White angular acceleration density (1/s³) of each bone direction's constant-velocity model.
Both were chosen on training subjects 02 and 05 (jittered and clean, at 120 and 30 fps) as the
values that kept the most segment-direction error off jittered frames while moving clean frames
by about 0.1° or less."""

NOISE_WINDOW = 48
"""Second differences per value in the running median of the noise (0.4 s at 120 fps)."""

_MIN_FRAMES = 8  # second differences seen before the noise estimate is used (before: pass through)
_NOISE_EVERY = 4  # frames between re-estimates: the noise changes slowly, a median costs ~10 µs
_START_VELOCITY_VAR = 100.0  # the first frame's velocity is unknown: a wide prior the next sets
_GAUSS_MAD = 0.6745  # the median of |N(0, 1)|
_SECOND_DIFF_VAR = 6.0  # var(x[t] − 2x[t−1] + x[t−2]) / σ² for white noise of σ
_SHORT_BONE_M = 1e-6  # a bone this short has no direction: it is rebuilt as sent


class JitterFilter:
    """``filter(positions (J, 3), t_s)`` → the joint positions with their frame-to-frame jitter
    filtered (see the module docstring); ``t_s`` is the sender's timestamp in seconds, strictly
    increasing within a stream. ``parents[j]`` is joint j's parent (-1 for the root, joint 0);
    parents come before their children.

    One frame is one call of a compiled CasADi SX graph (:func:`_step_function`: the bones'
    directions, the Kalman predict and update of every row, the frame rebuilt), bound to this
    object's arrays; only the running median of the noise is numpy. :attr:`noise` is each row's
    estimated jitter σ after the last frame: the root's in metres, each bone direction's in
    radians (about)."""

    def __init__(
        self,
        parents: Sequence[int],
        *,
        root_process_noise: float = ROOT_PROCESS_NOISE,
        direction_process_noise: float = DIRECTION_PROCESS_NOISE,
        window: int = NOISE_WINDOW,
    ) -> None:
        pars = validated_parents(parents)
        for name, q in (("root", root_process_noise), ("direction", direction_process_noise)):
            if not (np.isfinite(q) and q > 0.0):
                raise ValueError(f"{name} process noise must be a finite number > 0, got {q}")
        if window < _MIN_FRAMES:
            raise ValueError(f"window must be at least {_MIN_FRAMES} frames, got {window}")
        self.num_joints = len(pars)
        self._window = window
        fn = _step_function(pars, float(root_process_noise), float(direction_process_noise))
        self._step = CompiledFunction(fn)
        self._positions, self._state, self._r, self._dt, self._start = self._step.args
        self._out, self._d2_now, self._state_next = self._step.res
        self._d2 = np.zeros((self.num_joints, window, 3))  # ring of |second differences| per row
        self.reset()

    def reset(self) -> None:
        """A new stream: the next frame passes through and starts the filter."""
        self._t: float | None = None
        self._frames = 0
        self._r[:] = 0.0
        self.noise = np.zeros(self.num_joints)

    def __call__(self, positions: npt.ArrayLike, t_s: float) -> FloatArray:
        p = np.asarray(positions, dtype=np.float64)
        j = self.num_joints
        if p.shape != (j, 3):
            raise ValueError(f"positions must be ({j}, 3), got {p.shape}")
        if not np.isfinite(p).all():  # one would poison the stream's filter state for good
            bad = sorted({int(i) for i in np.nonzero(~np.isfinite(p))[0]})
            raise ValueError(f"positions of joints {bad} are not finite")
        t = float(t_s)
        if self._t is not None and not t > self._t:
            raise ValueError(f"frame time {t} s is not after the previous frame's {self._t} s")
        self._start[0] = 1.0 if self._t is None else 0.0
        self._dt[0] = 1.0 if self._t is None else t - self._t
        self._t = t
        np.copyto(self._positions, p.reshape(-1))
        self._step()
        np.copyto(self._state, self._state_next)
        self._frames += 1
        if self._frames >= 3:  # two frames as sent before this one: a second difference
            self._record_second_difference(self._frames - 3)
        return self._out.reshape(j, 3).copy()

    def _record_second_difference(self, index: int) -> None:
        """Record the stream's ``index``-th second difference (from 0); re-estimate the noise."""
        j, window = self.num_joints, self._window
        self._d2[:, index % window] = self._d2_now.reshape(j, 3)
        n = min(index + 1, window)
        if n >= _MIN_FRAMES and (n < window or (index + 1) % _NOISE_EVERY == 0):
            seen = self._d2[:, :n].reshape(j, -1)
            mad = np.partition(seen, seen.shape[1] // 2, axis=1)[:, seen.shape[1] // 2]
            self.noise = mad / (_GAUSS_MAD * np.sqrt(_SECOND_DIFF_VAR))
            self._r[:] = self.noise**2


_STATE_ROWS = 7  # x, v, p11, p12, p22 (the Kalman state), and the last two frames as sent


@memoized_graph
def _step_function(parents: tuple[int, ...], q_root: float, q_direction: float) -> ca.Function:
    """One frame: ``(positions J·3, state 7·J·3, noise variance J, dt, start) → (positions
    J·3, |second difference| J·3, state 7·J·3)``, row-major. The rows filtered are the root's
    position and each bone's unit direction; the state holds per coordinate the estimate x,
    its velocity v, their covariance [[p11, p12], [p12, p22]], and the last two frames' rows as
    sent. ``start`` 1: the frame starts the stream (x = the frame, v unknown)."""
    j = len(parents)
    p_in = ca.SX.sym("positions", 3 * j)
    state = ca.SX.sym("state", _STATE_ROWS * 3 * j)
    r_in = ca.SX.sym("r", j)
    dt = ca.SX.sym("dt")
    start = ca.SX.sym("start")

    def rows(v: ca.SX) -> list[list[ca.SX]]:
        return [[v[3 * i + c] for c in range(3)] for i in range(j)]

    pos = rows(p_in)
    x, v, p11, p12, p22, sent1, sent0 = (rows(state[k * 3 * j : (k + 1) * 3 * j]) for k in range(7))
    bones = [[ca.SX(0.0)] * 3] + [
        [pos[i][c] - pos[parents[i]][c] for c in range(3)] for i in range(1, j)
    ]
    lengths = [ca.SX(0.0)] + [ca.sqrt(sum(b * b for b in bones[i])) for i in range(1, j)]
    short = [ca.SX(1.0)] + [lengths[i] < _SHORT_BONE_M for i in range(1, j)]
    z = [pos[0]] + [
        [bones[i][c] / ca.if_else(short[i], 1.0, lengths[i]) for c in range(3)] for i in range(1, j)
    ]
    new: list[list[list[ca.SX]]] = [[], [], [], [], []]
    d2: list[ca.SX] = []
    for i in range(j):
        q = q_root if i == 0 else q_direction
        row: list[list[ca.SX]] = [[], [], [], [], []]
        for c in range(3):
            # Predict: constant velocity, white acceleration of density q.
            x_pred = x[i][c] + dt * v[i][c]
            a11 = p11[i][c] + dt * (2.0 * p12[i][c] + dt * p22[i][c]) + q * dt**3 / 3.0
            a12 = p12[i][c] + dt * p22[i][c] + q * dt**2 / 2.0
            a22 = p22[i][c] + q * dt
            # Update (a11 > 0 after any prediction with dt > 0, so the sum is > 0).
            k1 = a11 / (a11 + r_in[i])
            k2 = a12 / (a11 + r_in[i])
            innovation = z[i][c] - x_pred
            values = (
                x_pred + k1 * innovation,
                v[i][c] + k2 * innovation,
                (1.0 - k1) * a11,
                (1.0 - k1) * a12,
                a22 - k2 * a12,
            )
            first = (z[i][c], ca.SX(0.0), ca.SX(0.0), ca.SX(0.0), ca.SX(_START_VELOCITY_VAR))
            for k in range(5):
                row[k].append(ca.if_else(start, first[k], values[k]))
            d2.append(ca.fabs(z[i][c] - 2.0 * sent1[i][c] + sent0[i][c]))
        for k in range(5):
            new[k].append(row[k])
    # The frame rebuilt root outward: the filtered directions at the lengths as sent. A bone
    # too short to have a direction is kept as sent. One whose filtered direction all but
    # vanished (its sent directions cancel out: a joint that sits on its parent, as CMU
    # MotionBuilder rigs put Spine on the Hips, seen through jitter) keeps the filtered
    # vector, shrunk as it is: rebuilt as sent it had carried its parent's raw jitter into
    # everything above it (the whole upper body jittered with the root, the trunk frame 2.2°
    # off on root jitter alone; 1.2° now).
    xs = new[0]
    out = [xs[0]]
    for i in range(1, j):
        norm = ca.sqrt(sum(e * e for e in xs[i]))
        unscaled = ca.logic_or(short[i], norm < 0.5)
        scale = lengths[i] / ca.if_else(unscaled, 1.0, norm)
        bone = [ca.if_else(short[i], bones[i][c], xs[i][c] * scale) for c in range(3)]
        out.append([out[parents[i]][c] + bone[c] for c in range(3)])

    def flat(m: list[list[ca.SX]]) -> list[ca.SX]:
        return [e for row in m for e in row]

    state_next = ca.vertcat(*[e for m in (*new, z, sent1) for e in flat(m)])
    return compile_graph(
        "jitter_filter_step",
        [p_in, state, r_in, dt, start],
        [ca.vertcat(*flat(out)), ca.vertcat(*d2), state_next],
    )

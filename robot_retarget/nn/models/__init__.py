"""Retargeting models behind one interface: copy baselines, NKN, PMnet, TDCN and our residual
model.

Import the registry for names → models (``from robot_retarget.nn.models.registry import
build_model``); this file imports nothing, so one broken model never breaks the others.

Where we deviate from (or fill gaps in) the papers, and why:

- Features (both): velocities are *backward* differences (frame 0 is zero) so frame t needs no
  future frame; heading = yaw of the hips' left-right axis; the target's root is integrated
  from the source's first position and heading. Inputs are standardised with statistics fitted
  from training data (``fit_normalization``); the papers do not give their normalisation.
- Losses (both): ‖·‖² terms are summed over features and averaged over frames and batch, so
  the published weights act per frame whatever the window length. The twist ("euler_y") is
  measured about each joint's own bone axis (the direction to its first child; leaves use
  their own bone), since our canonical bones are not all along y; the root is excluded. GAN
  generator terms are the papers' saturating log(1 − D), computed from logits.
- NKN: GRU widths, β, α, λ, ω, Adam 1e-4, clip 25 and the 0.3 balancing rule as published;
  x̂_0 = 0; the discriminator's channel widths (64, 128, 256, 512) are ours (not published).
- PMnet: Table 1 layer sizes, λ_p, λ_m, λ_r, α, dropout keep 0.8 as published; N_s = 1 (our
  offsets are metres); "joints that affect the end effectors" read as each effector's own chain
  (Shoulder…Hand, UpLeg…ToeBase, Neck…Head), trunk weight 1; F_M's convolutions are causal
  (``causal_movement=True``) so the online path has no look-ahead; the mean-point trajectory is
  taken relative to the window's first root position and heading.
- TDCN (robot_retarget.nn.models.tdcn): the paper's layers, receptive field 81 and losses
  (height loss, 31-frame patch discriminator, least squares); 256 channels instead of 1024
  (the live step budget); causal by default (the paper's ablation A5) so it streams, centred
  with ``causal=False``; rotations and root movement predicted as corrections of the source's
  (copy-scaled at the start); every layer pads with its first / last frame.
- Residual (ours, robot_retarget.nn.models.residual): PMnet's q_B = q_A ⊗ Δq with q_A the
  source's measured rotations (denoised by a learned causal filter) instead of a regression
  from positions, root motion as copy-scaled's through a unit-gain causal filter, trained on
  differentiable versions of the eval metrics (robot_retarget.nn.retarget_losses) and on
  corrupted input. It exists because the papers' models, trained here, lost to copying the
  rotations on every pose metric (PMnet: bone direction 19° vs 5.7°); it starts as copy-scaled
  and learns only corrections.
"""

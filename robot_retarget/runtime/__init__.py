"""The networks as the live path runs them: numpy only, no torch.

- :mod:`~robot_retarget.runtime.model`: :class:`RuntimeModel` (architecture + weights) and its
  ``.npz`` file format, written by ``export`` and ``train``;
- :mod:`~robot_retarget.runtime.loader`: a model by name or path, torch only as a fallback;
- one step per architecture: :mod:`~robot_retarget.runtime.copy` (``copy``, ``copy-scaled``),
  :mod:`~robot_retarget.runtime.residual` (the shipped default),
  :mod:`~robot_retarget.runtime.pmnet`, :mod:`~robot_retarget.runtime.tdcn` (the causal TDCN's
  ring-buffer step, and whole clips of either TDCN);
- :mod:`~robot_retarget.runtime.frame`: shared per-frame plumbing (quaternions, tree FK,
  heading and root velocity).

Each step equals its torch model's online step to float32 rounding (tests/pipeline). The torch
models (robot_retarget.nn) import their weight layouts from here, never the reverse.
"""

"""The normaliser's statistics for a policy, from its demonstrations (round 0; they stay fixed after).

Observations: the demonstrations' frames, or for a policy of relative poses (`policy.frame`) every
training window's observations in its frame. Actions: the dims the spec ranges (`ranged_action_dims`)
over the spec's action box (`action_range = workspace`) or over the data's widened range
(`demonstrations`; a relative policy's in its frame), the rest as they are.
"""

from __future__ import annotations

import numpy as np

from soe_jax.data.episodes import policy_frames, policy_windows
from soe_jax.data.spec import PolicySpec
from soe_jax.policies import normalizer as normalizer_lib
from soe_jax.policies.policy import Policy
from soe_jax.train import fit as fit_lib


def fit_normalizer(policy: Policy, spec: PolicySpec, demos: list[dict], action_range: str, margin: float,
                   obs_min_span: np.ndarray | None = None) -> normalizer_lib.Normalizer:  # fmt: skip
  if policy.frame is None:
    obs, actions = policy_frames(demos, policy.lowdim_keys)
  else:
    w = fit_lib.in_frame(policy_windows(demos, policy), policy.frame)
    obs, actions = (
      np.asarray(w["obs"]).reshape(-1, policy.obs_dim),
      np.asarray(w["actions"]).reshape(-1, policy.action_dim),
    )
  box = spec.action_bounds() if action_range == "workspace" else None
  if action_range == "workspace" and box is None:
    raise ValueError("policy.action_range=workspace needs the spec's action_box; without one use demonstrations")
  return normalizer_lib.fit(obs, actions, margin, obs_min_span, action_box=box, ranged=spec.ranged_action_dims())

"""Every training target against the box the action normaliser maps to [-1, 1] (`policy.action_range`).

Under `workspace` (the task's box, `envs.<task>.WORKSPACE`) a recorded action outside the box is an
error that names the file, episode, step and dimension: training would clip it, so the policy would learn
another action than the one recorded. Under `demonstrations` (the demonstrations' widened range, kept to
reproduce earlier runs) targets outside are clipped, as they always were; the fit's record says what
fraction of the actions had a coordinate clipped, and a warning says so when it is not zero.
"""

from __future__ import annotations

import numpy as np
from absl import logging

from soe_jax.data.episodes import EpisodeSet, policy_windows
from soe_jax.data.spec import PolicySpec
from soe_jax.policies.normalizer import Normalizer
from soe_jax.runtime.errors import UserError
from soe_jax.train import fit as fit_lib


def dimension_name(spec: PolicySpec, d: int) -> str:
  """Action dimension `d` -> e.g. 'robot0 position[1]'."""
  for k, arm in enumerate(spec.actions):
    for part, size in arm:
      if d < size:
        return f"robot{k} {part}[{d}]"
      d -= size
  raise IndexError(f"the action has no dimension {d}")


def check(sets: list[EpisodeSet], norm: Normalizer, spec: PolicySpec, mode: str, path_of, policy=None) -> float:
  """The fraction of the actions in `sets` with a coordinate outside the normaliser's box (0 under
  `workspace`, where one is a `UserError`); `path_of(set)` names the file a set was read from. For a
  policy of relative poses (`policy.frame`), of the actions of every training window in its frame."""
  if policy is not None and policy.frame is not None:
    episodes = [ep for s in sets for ep in s.episodes]
    w = fit_lib.in_frame(policy_windows(episodes, policy), policy.frame)
    return _report(float(np.mean(norm.outside(np.asarray(w["actions"])).any(-1))))
  outside, total = 0, 0
  for s in sets:
    for i, ep in enumerate(s.episodes):
      actions = np.asarray(ep["actions"])
      out = norm.outside(actions)
      total += len(actions)
      if not out.any():
        continue
      if mode == "workspace":
        t, d = map(int, np.argwhere(out)[0])
        lo, hi = (np.asarray(x, np.float64) for x in (norm.unnormalize_actions(-1.0), norm.unnormalize_actions(1.0)))
        raise UserError(
          f"{path_of(s)}: episode {ep.get('episode_index', i)}, step {t}: action dimension {d} ({dimension_name(spec, d)}) is "
          f"{actions[t, d]:.5f}, outside the action box [{lo[d]:.5f}, {hi[d]:.5f}] (policy.action_range="
          "workspace: the task's workspace); training would clip it. Record actions inside the box, or "
          "use policy.action_range=demonstrations"
        )
      outside += int(out.any(-1).sum())
  return _report(outside / max(total, 1))


def _report(fraction: float) -> float:
  if fraction > 0:
    logging.warning(
      "%.2f%% of the training actions have a coordinate outside the demonstrations' action range and are "
      "clipped to it (policy.action_range=demonstrations; the workspace box clips none)",
      100 * fraction,
    )
  return fraction

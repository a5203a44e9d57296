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


def _part(spec: PolicySpec, d: int) -> tuple[int, str, int]:
  """Action dimension `d` -> (arm, part, index within the part)."""
  for k, arm in enumerate(spec.actions):
    for part, size in arm:
      if d < size:
        return k, part, d
      d -= size
  raise IndexError(f"the action has no dimension {d}")


def dimension_name(spec: PolicySpec, d: int) -> str:
  """Action dimension `d` -> e.g. 'robot0 position[1]'."""
  k, part, i = _part(spec, d)
  return f"robot{k} {part}[{i}]"


def check(sets: list[EpisodeSet], norm: Normalizer, spec: PolicySpec, mode: str, path_of, policy=None) -> float:
  """The fraction of the actions in `sets` with a coordinate outside the normaliser's box (0 under
  `workspace`, where one is a `UserError`); `path_of(set)` names the file a set was read from. For a
  policy of relative poses (`policy.frame`), of the actions of every training window in its frame."""
  if policy is not None and policy.frame is not None:
    episodes = [ep for s in sets for ep in s.episodes]
    w = fit_lib.in_frame(policy_windows(episodes, policy), policy.frame)
    out = norm.outside(np.asarray(w["actions"])).reshape(-1, spec.action_dim)
    return _report(int(out.any(-1).sum()), out.sum(0), len(out), spec)
  outside, per_dim, total = 0, np.zeros(spec.action_dim, int), 0
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
      per_dim += out.reshape(-1, spec.action_dim).sum(0)
  return _report(outside, per_dim, total, spec)


def _report(outside: int, per_dim: np.ndarray, total: int, spec: PolicySpec) -> float:
  """The fraction of `total` actions with a coordinate clipped (`outside` of them; `per_dim` (A,): how
  many per dimension), with a warning naming each clipped part and dimension and why it clips."""
  fraction = outside / max(total, 1)
  if fraction == 0:
    return fraction
  dims = np.flatnonzero(per_dim)
  ranged = spec.ranged_action_dims()
  named = ", ".join(f"{dimension_name(spec, d)} in {100 * per_dim[d] / total:.1f}%" for d in dims)
  why = []
  if ranged[dims].any():
    why.append("a part normalised by range is clipped to the demonstrations' range (policy.action_range="
               "demonstrations; the workspace box clips none)")  # fmt: skip
  left = sorted({(k, part) for k, part, _ in (_part(spec, d) for d in dims if not ranged[d])})
  if left:
    parts = ", ".join(f"robot{k} {part}" for k, part in left)
    fields = ", ".join(sorted({f"dataset.normalize.{part}=range" for _, part in left}))
    why.append(f"{parts} is left as it is (identity), so the policy can command only [-1, 1] of it: normalise "
               f"it by its range (a robot's config: {fields})")  # fmt: skip
  logging.warning(
    "%.2f%% of the training actions have a coordinate outside [-1, 1] once normalised and are clipped to it: %s. %s",
    100 * fraction,
    named,
    "; ".join(why),
  )
  return fraction

"""A task's workspace box: per robot, the range of every position its scripted demonstrator commands over
whole episodes from many start states, widened by a margin. The policy's action normaliser maps it to
[-1, 1] (`policy.action_range = workspace`), so every grasp the task can ask for is inside what the
policy can command, whatever the few demonstrations it was fitted on happened to cover.

  python -m soe_jax experts --task=lift --workspace --num_episodes=1000 --seed=90001

prints the box; the task file keeps it (`WORKSPACE`) with that command. The seed is one no run uses
(demonstrations use `data.demo_seed`, evaluation `eval.seed`, exploration the training seed's stream).
"""

from __future__ import annotations

import jax
import numpy as np

from soe_jax.envs.registry import make_env
from soe_jax.experts import collect
from soe_jax.experts import registry as expert_registry

SEED = 90001  # the start states the committed boxes come from
MARGIN = 0.02  # m added on each side of the commanded range
BATCH = 250  # episodes per batch (memory)


def commanded_range(task: str, num_episodes: int, seed: int, backend: str = "auto", progress: bool = True):
  """(lo, hi), each (num_robots, 3): the range of the positions the demonstrator of `task` commands on
  every step of its episodes (up to and including the successful step; the whole episode where it
  fails) from `num_episodes` start states of `seed`, and the demonstrator's success rate."""
  env = make_env(task, backend=backend)
  if env.action_mode != "absolute":
    raise ValueError(f"the workspace box is of absolute positions, not {env.action_mode!r} actions")
  expert = expert_registry.make_expert(task)
  keys = jax.random.split(jax.random.key(seed), num_episodes)
  lo = np.full((env.num_robots, 3), np.inf)
  hi = -lo
  successes = 0
  for start in range(0, num_episodes, BATCH):
    batch = collect.run_demos(env, expert, keys[start : start + BATCH], progress=progress)
    actions = batch["actions"].reshape(*batch["actions"].shape[:2], env.num_robots, -1)[..., :3]  # (N, T, R, 3)
    valid = np.arange(actions.shape[1])[None, :] < batch["length"][:, None]  # (N, T)
    pos = actions[valid]  # (steps, R, 3)
    lo, hi = np.minimum(lo, pos.min(0)), np.maximum(hi, pos.max(0))
    successes += int(batch["success"].sum())
  return lo, hi, successes / num_episodes


def derive(task: str, num_episodes: int, seed: int = SEED, margin: float = MARGIN, backend: str = "auto") -> dict:
  """The workspace box of `task` -> {task, num_episodes, seed, margin, commanded: per robot [lo, hi],
  box: per robot [lo, hi] widened by `margin`, expert_success_rate}, positions in m rounded to 0.1 mm
  outwards."""
  lo, hi, rate = commanded_range(task, num_episodes, seed, backend)
  box_lo = np.floor((lo - margin) * 1e4) / 1e4
  box_hi = np.ceil((hi + margin) * 1e4) / 1e4
  pairs = lambda a, b: [[[round(float(x), 5) for x in a[k]], [round(float(x), 5) for x in b[k]]] for k in range(len(a))]
  return dict(
    task=task,
    num_episodes=num_episodes,
    seed=seed,
    margin=margin,
    commanded=pairs(lo, hi),
    box=pairs(box_lo, box_hi),
    expert_success_rate=rate,
  )

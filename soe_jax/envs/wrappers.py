"""brax's training wrappers (vmap, episode, auto-reset), composed by one function."""

from __future__ import annotations

from brax.envs.base import Env
from brax.envs.wrappers import training


def wrap_env(env: Env, episode_length: int | None = None, auto_reset: bool = True) -> Env:
  """Vmap over a batch of raw (uint32, shape (B, 2)) keys, count steps to `episode_length`
  (default: the task's episode length), and optionally reset an environment to its start state when it is
  done, as brax does. Batched `reset(keys)` / `step(states, actions)` follow."""
  length = episode_length if episode_length is not None else getattr(env, "episode_length", 1000)
  wrapped = training.EpisodeWrapper(training.VmapWrapper(env), length, action_repeat=1)
  return training.AutoResetWrapper(wrapped) if auto_reset else wrapped

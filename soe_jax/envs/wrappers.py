"""Batched environments with episode counting and optional auto-reset, composed by one function."""

from __future__ import annotations

from soe_jax.envs import mjx_import  # noqa: F401 (first: MJX quietly, before brax imports it)

# isort: split
import jax
import jax.numpy as jnp
from brax.envs.base import Env, State, Wrapper
from brax.envs.wrappers import training


class EpisodeAutoReset(Wrapper):
  """One environment: count steps, end an episode at success or after `episode_length` steps, and put
  an ended environment back to its start state (physics through the backend's own `where`, which
  leaves MuJoCo Warp's buffers shared by a batch alone; brax's tree `where` would not know them).
  `info["steps"]` counts the episode's steps, `info["truncation"]` marks an end by length alone."""

  def __init__(self, env: Env, episode_length: int):
    super().__init__(env)
    self.episode_length = episode_length

  def reset(self, rng: jax.Array) -> State:
    state = self.env.reset(rng)
    zero = jnp.zeros(())
    state.info.update(steps=zero, truncation=zero, first_pipeline_state=state.pipeline_state, first_obs=state.obs)
    return state

  def step(self, state: State, action: jax.Array) -> State:
    steps = jnp.where(state.done > 0, 0.0, state.info["steps"]) + 1
    nxt = self.env.step(state.replace(done=jnp.zeros_like(state.done)), action)
    out_of_time = steps >= self.episode_length
    done = jnp.maximum(nxt.done, out_of_time.astype(nxt.done.dtype))
    first_ps, first_obs = state.info["first_pipeline_state"], state.info["first_obs"]
    ps = self.env.physics.where(done > 0, first_ps, nxt.pipeline_state)
    obs = jax.tree.map(lambda f, o: jnp.where(done > 0, f, o), first_obs, nxt.obs)
    info = dict(nxt.info, steps=steps, truncation=(out_of_time & (nxt.done == 0)).astype(jnp.float32))
    return nxt.replace(pipeline_state=ps, obs=obs, done=done, info=info)


def wrap_env(env: Env, episode_length: int | None = None, auto_reset: bool = True) -> Env:
  """Vmap over a batch of raw (uint32, shape (B, 2)) keys and count steps to `episode_length`
  (default: the task's episode length); with `auto_reset` an environment that is done starts again
  from its start state (`EpisodeAutoReset`, inside the vmap), else brax's episode wrapper.
  Batched `reset(keys)` / `step(states, actions)` follow."""
  length = episode_length if episode_length is not None else getattr(env, "episode_length", 1000)
  if auto_reset:
    return training.VmapWrapper(EpisodeAutoReset(env, length))
  return training.EpisodeWrapper(training.VmapWrapper(env), length, action_repeat=1)

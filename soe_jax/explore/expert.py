"""`expert`: the task's scripted demonstrator resumed from the current state (an oracle; for tests and
as a ceiling, not a method), `demonstrate`, and steering's scripted chooser, which follows it."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp

from soe_jax.envs import observations
from soe_jax.experts import registry as expert_registry
from soe_jax.experts import script
from soe_jax.types import Strategy

if TYPE_CHECKING:
  from soe_jax.envs.manipulation import ManipulationEnv


def demonstrate(env: ManipulationEnv, expert: script.ScriptedExpert | script.BimanualExpert, env_state, num_steps: int):
  """The demonstrator's next `num_steps` actions (B, num_steps, A) from each environment's current
  state, resumed at the phase the scene shows, simulated on a copy of the state. Its random
  parameters come from the episode's reset key (as in the demonstrations), so they stay fixed."""
  expert_keys = jax.vmap(lambda k: jax.random.fold_in(k, 1))(env_state.info["rng"])
  es = jax.vmap(lambda o, k: expert.init(o, k, resume=True))(env_state.obs, expert_keys)
  step, act = jax.vmap(env.step), jax.vmap(expert.act)

  def body(carry, _):
    state, es = carry
    action, es = act(es, state.obs)
    return (step(state, action), es), action

  _, actions = jax.lax.scan(body, (env_state, es), None, length=num_steps)
  return actions.swapaxes(0, 1)


def task_env(strategy: str, env: ManipulationEnv | None) -> ManipulationEnv:
  if env is None:
    raise ValueError(f"strategy {strategy!r} follows the task's demonstrator and needs its environment (env=...)")
  return env


@dataclasses.dataclass(frozen=True)
class ScriptedChooser:
  """DESIGN.md's oracle chooser for `soe_steer`: the proposal whose end-effector paths (its commanded
  positions, every arm's) are closest in mean L2 distance to the scripted demonstrator's next positions
  from the current state."""

  env: ManipulationEnv
  expert: script.ScriptedExpert | script.BimanualExpert

  @classmethod
  def create(cls, strategy: str, env: ManipulationEnv | None) -> ScriptedChooser:
    env = task_env(strategy, env)
    return cls(env, expert_registry.make_expert(env.name))

  def positions(self, actions: jax.Array) -> jax.Array:
    """(..., A) actions -> (..., R, 3): each arm's commanded position."""
    return observations.action_positions(actions, self.env.num_robots)

  def __call__(self, candidates: jax.Array, env_state, key):
    """candidates (B, C, Ta, A) raw -> (index (B,), distance (B,))."""
    reference = demonstrate(self.env, self.expert, env_state, candidates.shape[2])
    gap = jnp.linalg.norm(self.positions(candidates) - self.positions(reference)[:, None], axis=-1)  # (B, C, Ta, R)
    dist = jnp.mean(gap, axis=(-2, -1))
    return jnp.argmin(dist, axis=1), jnp.min(dist, axis=1)


@dataclasses.dataclass(frozen=True)
class Expert(Strategy):
  env: ManipulationEnv = dataclasses.field(default=None, metadata=dict(setting=False))
  expert: script.ScriptedExpert | script.BimanualExpert = dataclasses.field(default=None, metadata=dict(setting=False))
  name = "expert"

  @classmethod
  def create(cls, env=None, **settings):
    env = task_env(cls.name, env)
    return cls(env=env, expert=expert_registry.make_expert(env.name), **settings)

  def __call__(self, agent, obs_history, env_state, key):
    return demonstrate(self.env, self.expert, env_state, agent.policy.n_action_steps), {}

"""`soe_steer`: steering (DESIGN.md, "Steering"). Proposals along the effective latent dimensions, a
diverse few per dimension by farthest point sampling, one picked by a chooser, at every `every`-th
decision of an episode, the base path between. Unattended runs use the scripted chooser, an oracle
that follows the task's demonstrator; the steering page puts a person in its place."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp

from soe_jax.envs import observations
from soe_jax.experts import registry as expert_registry
from soe_jax.experts import script
from soe_jax.explore import expert as expert_strategy
from soe_jax.explore import steering
from soe_jax.policies import agent as agent_lib
from soe_jax.types import Chooser, Strategy

if TYPE_CHECKING:
  from soe_jax.envs.manipulation import ManipulationEnv


@dataclasses.dataclass(frozen=True)
class ScriptedChooser:
  """DESIGN.md's oracle chooser: the proposal whose end-effector paths (its commanded positions, every
  arm's) are closest in mean L2 distance to the scripted demonstrator's next positions from the
  current state."""

  env: ManipulationEnv
  expert: script.ScriptedExpert | script.BimanualExpert

  def __call__(self, candidates: jax.Array, env_state, key):
    """candidates (B, C, Ta, A) raw -> (index (B,), distance (B,))."""
    reference = expert_strategy.demonstrate(self.env, self.expert, env_state, candidates.shape[2])
    positions = lambda a: observations.action_positions(a, self.env.num_robots)
    gap = jnp.linalg.norm(positions(candidates) - positions(reference)[:, None], axis=-1)  # (B, C, Ta, R)
    dist = jnp.mean(gap, axis=(-2, -1))
    return jnp.argmin(dist, axis=1), jnp.min(dist, axis=1)


@dataclasses.dataclass(frozen=True)
class SoeSteer(Strategy):
  """Steering along `dims` with `chooser`. `prepare` sets `dims`: the effective latent dimensions over
  `snr_windows` windows of the round's data (SNR above `threshold_db`), at most `max_dims` (0: all)."""

  alpha: float = 2.0
  num_proposals: int = 32
  num_choices: int = 5
  every: int = 1
  threshold_db: float = 0.0
  max_dims: int = 0
  snr_windows: int = 2048
  chooser: Chooser = dataclasses.field(default=None, metadata=dict(setting=False))
  num_robots: int = dataclasses.field(default=1, metadata=dict(setting=False))  # the task's arms
  dims: tuple[int, ...] = dataclasses.field(default=(), metadata=dict(setting=False))
  name = "soe_steer"

  @classmethod
  def create(cls, env=None, **settings):
    env = expert_strategy.task_env(cls.name, env)
    chooser = ScriptedChooser(env, expert_registry.make_expert(env.name))
    return cls(chooser=chooser, num_robots=env.num_robots, **settings)

  def snr(self, agent, buffer, key) -> jax.Array:
    """(d,) SNR in dB of the agent's latent dimensions over the buffer's data."""
    return steering.buffer_snr(agent, buffer, key, self.snr_windows)

  def prepare(self, agent, buffer, key):
    snr = self.snr(agent, buffer, key)
    dims = steering.effective_dims(snr, self.threshold_db, self.max_dims or None)
    return dataclasses.replace(self, dims=dims), dict(snr_db=[round(float(x), 2) for x in snr], steer_dims=list(dims))

  def candidates(self, agent, obs_history, key, dims: tuple[int, ...]):
    positions = lambda a: observations.action_positions(a, self.num_robots)
    return steering.candidates(
      agent, obs_history, key, dims, self.alpha, self.num_proposals, self.num_choices, positions
    )

  def __call__(self, agent, obs_history, env_state, key):
    b = agent_lib.batch_size(obs_history)
    decision = env_state.info["steps"][0] // agent.policy.n_action_steps  # the batch decides together
    key_base, key_steer, key_choose = jax.random.split(key, 3)

    def base(_):
      return agent.act(obs_history, key_base), jnp.full(b, -1, jnp.int32), jnp.zeros(b)

    def steer(_):
      cands, dim_of = self.candidates(agent, obs_history, key_steer, self.dims)
      index, dist = self.chooser(cands, env_state, key_choose)
      return jnp.take_along_axis(cands, index[:, None, None, None], axis=1)[:, 0], dim_of[index], dist

    if not self.dims:
      actions, dim, dist = base(None)
      steered = jnp.zeros(b, bool)
    else:
      steered_now = decision % self.every == 0
      actions, dim, dist = jax.lax.cond(steered_now, steer, base, None)
      steered = jnp.broadcast_to(steered_now, (b,))
    return actions, {"steered": steered, "dim": dim, "distance": dist}

"""`soe_steer`: steering (DESIGN.md, "Steering"). Proposals along the effective latent dimensions, a
diverse few per dimension by farthest point sampling, one picked by a chooser, at every `every`-th
decision of an episode, the base path between. Unattended runs use the scripted chooser, an oracle
that follows the task's demonstrator; the steering page puts a person in its place."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import jax
import jax.numpy as jnp

from soe_jax import registry
from soe_jax.explore import soe, steering
from soe_jax.policies import agent as agent_lib
from soe_jax.types import Chooser, Strategy


@dataclasses.dataclass(frozen=True)
class SoeSteer(Strategy):
  """Steering along `dims` with `chooser`. `prepare` sets `dims`: the effective latent dimensions over
  `snr_windows` windows of the round's data (SNR above `threshold_db`), at most `max_dims` (0: all).
  `positions` maps actions (..., A) to each arm's commanded position (..., R, 3), over which the
  proposals are spread. This module imports no simulator (a robot's server reads these settings)."""

  alpha: float = soe.ALPHA
  num_proposals: int = 32
  num_choices: int = 5
  every: int = 1
  threshold_db: float = 0.0
  max_dims: int = 0
  snr_windows: int = 2048
  chooser: Chooser = dataclasses.field(default=None, metadata=dict(setting=False))
  positions: Callable[[jax.Array], jax.Array] = dataclasses.field(default=None, metadata=dict(setting=False))
  dims: tuple[int, ...] = dataclasses.field(default=(), metadata=dict(setting=False))
  name = "soe_steer"

  @classmethod
  def create(cls, env=None, **settings):
    # The scripted chooser follows the task's demonstrator, which imports the simulator: loaded by name
    # (as the registries load tasks) so that reading steering's settings imports none of it.
    chooser = registry.load("soe_jax.explore.expert:ScriptedChooser").create(cls.name, env)
    return cls(chooser=chooser, positions=chooser.positions, **settings)

  def snr(self, agent, buffer, key) -> jax.Array:
    """(d,) SNR in dB of the agent's latent dimensions over the buffer's data."""
    return steering.buffer_snr(agent, buffer, key, self.snr_windows)

  def prepare(self, agent, buffer, key):
    snr = self.snr(agent, buffer, key)
    dims = self.effective_dims(snr)
    return dataclasses.replace(self, dims=dims), dict(snr_db=[round(float(x), 2) for x in snr], steer_dims=list(dims))

  def effective_dims(self, snr_db) -> tuple[int, ...]:
    """The dimensions steered along, given each latent dimension's SNR in dB (highest first)."""
    return steering.effective_dims(snr_db, self.threshold_db, self.max_dims or None)

  def candidates(self, agent, obs_history, key, dims: tuple[int, ...]):
    return steering.candidates(
      agent, obs_history, key, dims, self.alpha, self.num_proposals, self.num_choices, self.positions
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

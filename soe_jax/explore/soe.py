"""`soe`: on-manifold exploration, the exploration path a~ = D(q_phi(z)) with z ~ N(mu, (alpha sigma)^2).

z = mu(o) + alpha sigma(o) eps with eps ~ N(0, I) drawn afresh at every decision (chunk), or, with
`hold` > 1, the same eps for `hold` consecutive decisions of an episode: the latent keeps its
direction relative to the posterior of each new observation (z itself still follows the
observations, which a fixed z would ignore).
"""

from __future__ import annotations

import dataclasses

import jax

from soe_jax.types import Strategy

_HOLD_STREAM = 0x50E  # the held noise's keys: a stream of their own beside the per-decision keys
ALPHA = 2.0  # the paper's exploration scale for most tasks (soe's, and steering's, default)


@dataclasses.dataclass(frozen=True)
class Soe(Strategy):
  alpha: float = ALPHA
  hold: int = 1  # decisions that share one draw of the latent's noise
  name = "soe"

  def __post_init__(self):
    if int(self.hold) < 1:
      raise ValueError(f"soe's hold must be at least 1 decision, got {self.hold}")

  def __call__(self, agent, obs_history, env_state, key):
    noise_key = None
    if self.hold > 1:
      decision = env_state.info["steps"][0] // agent.policy.n_action_steps  # the batch decides together
      stream = jax.random.fold_in(env_state.info["slice_key"][0], _HOLD_STREAM)
      noise_key = jax.random.fold_in(stream, decision // self.hold)
    chunk, z = agent.explore_chunk(obs_history, key, self.alpha, noise_key)
    return agent.executed(chunk), {"z": z}

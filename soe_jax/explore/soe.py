"""`soe`: on-manifold exploration, the exploration path a~ = D(q_phi(z)) with z ~ N(mu, (alpha sigma)^2)."""

from __future__ import annotations

import dataclasses

from soe_jax.types import Strategy


@dataclasses.dataclass(frozen=True)
class Soe(Strategy):
  alpha: float = 2.0  # the paper's exploration scale for most tasks
  name = "soe"

  def __call__(self, agent, obs_history, env_state, key):
    chunk, z = agent.explore_chunk(obs_history, key, self.alpha)
    return agent.executed(chunk), {"z": z}

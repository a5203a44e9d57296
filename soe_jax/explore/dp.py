"""`dp`: the base path a = D(E(o)), the plain Diffusion Policy baseline (and how evaluation acts)."""

from __future__ import annotations

import dataclasses

from soe_jax.types import Strategy


@dataclasses.dataclass(frozen=True)
class Dp(Strategy):
  name = "dp"

  def __call__(self, agent, obs_history, env_state, key):
    return agent.act(obs_history, key), {}

"""The head contract: a frozen dataclass of pure functions over a conditioning vector `cond` (B, G).

  init(key, cond_dim) -> params
  loss(params, cond, actions (B, T, A) normalised, key) -> (scalar loss, aux dict)
  sample(params, cond, key, cond_fn=None) -> (actions (B, T, A) normalised, aux dict)

`cond_fn(cond, step_index, key) -> cond` is applied before every call of the network while sampling.
`progress(step_index) -> u` says how far sampling has come at that call, in SIME's convention
u = 1 - k / num_train_timesteps for the diffusion timestep k (0 at pure noise, 1 at the data); SIME's
noise schedule is a function of it.
The VIB bypass only changes `cond`, so it works unchanged with every head.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any


@dataclasses.dataclass(frozen=True)
class Head:
  name: str
  action_dim: int
  horizon: int
  init: Callable[..., Any]
  loss: Callable[..., Any]
  sample: Callable[..., Any]
  progress: Callable[[Any], Any]
  module: Any = None  # the Flax module, for parameter counts and inspection

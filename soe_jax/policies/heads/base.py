"""The head contract: a frozen dataclass of pure functions over a conditioning vector `cond` (B, G).

  init(key, cond_dim) -> params
  loss(params, cond, actions (B, T, A) normalised, key) -> (scalar loss, aux dict)
  sample(params, cond, key, cond_fn=None) -> (actions (B, T, A) normalised, aux dict)

`cond_fn(cond, step_index, key) -> cond` is applied before every call of the network while sampling.
The VIB bypass only changes `cond`, so it works unchanged with every head.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable


@dataclasses.dataclass(frozen=True)
class Head:
  name: str
  action_dim: int
  horizon: int
  init: Callable[..., Any]
  loss: Callable[..., Any]
  sample: Callable[..., Any]
  module: Any = None  # the Flax module, for parameter counts and inspection

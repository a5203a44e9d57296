"""The training state pytree, its optimiser (AdamW, linear warm-up then cosine decay to 0, as diffusers'
"cosine" schedule) and Diffusion Policy's EMA of parameters."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import ml_collections
import optax
from flax import struct

from soe_jax.policies.normalizer import Normalizer


@struct.dataclass
class TrainState:
  step: jax.Array
  params: dict
  ema_params: dict | None  # None when EMA is off; evaluation then uses `params`
  opt_state: optax.OptState
  normalizer: Normalizer

  @property
  def eval_params(self) -> dict:
    """What evaluation and exploration use: the EMA weights when kept."""
    return self.ema_params if self.ema_params is not None else self.params


def make_optimizer(
  fit: ml_collections.ConfigDict, total_steps: int, lr: float | None = None
) -> optax.GradientTransformation:
  """AdamW(betas (0.95, 0.999), eps 1e-8, weight decay 1e-6 by default) with warm-up + cosine, peaking at
  `lr` (default `fit.lr`)."""
  peak = fit.lr if lr is None else lr
  schedule = optax.warmup_cosine_decay_schedule(
    0.0, peak, min(fit.warmup_steps, max(total_steps - 1, 1)), max(total_steps, 2), end_value=0.0
  )
  return optax.adamw(schedule, b1=fit.betas[0], b2=fit.betas[1], eps=fit.eps, weight_decay=fit.weight_decay)


def ema_decay(step: jax.Array, inv_gamma: float = 1.0, power: float = 0.75, max_value: float = 0.9999) -> jax.Array:
  """decay = 1 - (1 + s / inv_gamma)^-power with s = max(0, optimiser step - 1); 0 while s <= 0."""
  s = jnp.maximum(step - 1, 0).astype(jnp.float32)
  decay = 1.0 - (1.0 + s / inv_gamma) ** (-power)
  return jnp.where(s <= 0, 0.0, jnp.clip(decay, 0.0, max_value))


def ema_update(ema: dict, params: dict, decay: jax.Array) -> dict:
  return jax.tree.map(lambda e, p: decay * e + (1.0 - decay) * p, ema, params)


def create(params: dict, tx: optax.GradientTransformation, normalizer: Normalizer, ema: bool = True) -> TrainState:
  return TrainState(
    step=jnp.zeros((), jnp.int32),
    params=params,
    ema_params=jax.tree.map(jnp.copy, params) if ema else None,
    opt_state=tx.init(params),
    normalizer=normalizer,
  )

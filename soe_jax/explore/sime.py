"""`sime`: SIME's modal-level exploration (`specs/sime_baseline.md`), noise on the base path's
conditioning at every denoising call through the head sampler's `cond_fn` hook."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from soe_jax.policies.normalizer import Normalizer
from soe_jax.policies.policy import Policy
from soe_jax.types import CondFn, Strategy

IMAGE_SCALE = 0.5  # SIME's noise scale for image tasks (its state tasks': `Sime.scale`)


def gamma(u: jax.Array, tau1: float = 0.0, tau2: float = 1.0) -> jax.Array:
  """CADS' linear schedule: 1 for u <= tau1, 0 for u >= tau2, linear in between."""
  ramp = (tau2 - u) / max(tau2 - tau1, 1e-12)
  return jnp.where(u <= tau1, 1.0, jnp.where(u >= tau2, 0.0, ramp))


def noise_std(u: jax.Array, scale: float, tau1: float = 0.0, tau2: float = 1.0) -> jax.Array:
  """SIME's noise std s (1 - gamma(u)) at sampling progress u = 1 - k / T. As SIME's code runs it
  (u rises as the timestep k falls), the noise grows towards the last denoising step."""
  return scale * (1.0 - gamma(u, tau1, tau2))


def cond_fn(policy: Policy, normalizer: Normalizer, scale: float, tau1: float = 0.0, tau2: float = 1.0) -> CondFn:
  """c' = c + s (1 - gamma(u_i)) n with fresh n ~ N(0, I) at every denoising call i. For a low-dim
  policy SIME's s is in raw observation units; the conditioning is normalised, so each dimension's
  noise is scaled by that dimension's normalisation scale (d c = scale * d o), the same physical
  perturbation. For an image policy, as SIME's code runs image tasks (`specs/sime_baseline.md`), one s
  (SIME's 0.5) applies to the whole conditioning: every frame's image features and its low-dim vector."""
  if policy.image_keys:
    per_dim = jnp.ones(policy.cond_dim)
  elif policy.cond_dim == policy.n_obs_steps * policy.obs_dim:
    per_dim = jnp.tile(normalizer.obs_scale, policy.n_obs_steps)
  else:
    raise ValueError(
      "sime perturbs the low-dim conditioning; this policy's encoder gives "
      f"{policy.cond_dim} features for {policy.n_obs_steps} x {policy.obs_dim} observations"
    )

  def fn(cond, step_index, key):
    std = noise_std(policy.head.progress(step_index), scale, tau1, tau2)
    return cond + std * per_dim * jax.random.normal(key, cond.shape)

  return fn


@dataclasses.dataclass(frozen=True)
class Sime(Strategy):
  scale: float = 0.01  # SIME's raw-unit noise scale for state tasks (`IMAGE_SCALE` for image tasks)
  tau1: float = 0.0
  tau2: float = 1.0
  name = "sime"

  def __call__(self, agent, obs_history, env_state, key):
    fn = cond_fn(agent.policy, agent.normalizer, self.scale, self.tau1, self.tau2)
    return agent.act(obs_history, key, fn), {}

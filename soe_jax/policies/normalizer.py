"""Per-dimension limits normalisation (DESIGN.md, "Normalisation").

Low-dim observations and action positions map their range in the demonstrations, widened by a margin
on each side (default 10% of the range), to [-1, 1]; rotation-6d and gripper action dims stay as they
are (already in [-1, 1]). A dimension with (almost) no range is only shifted to 0. Normalised values
are clipped to [-1, 1] and the clipped fraction is reported. Statistics come from the demonstrations
once and are stored with the parameters. (Diffusion Policy's low-dim code uses one global scale for
observations; that quirk is not copied.)
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from flax import struct

RANGE_EPS = 1e-4


@struct.dataclass
class Normalizer:
  obs_scale: jnp.ndarray  # (D,)
  obs_offset: jnp.ndarray
  act_scale: jnp.ndarray  # (A,)
  act_offset: jnp.ndarray

  def normalize_obs(self, obs):
    return jnp.clip(obs * self.obs_scale + self.obs_offset, -1.0, 1.0)

  def normalize_actions(self, actions):
    return jnp.clip(actions * self.act_scale + self.act_offset, -1.0, 1.0)

  def unnormalize_actions(self, actions):
    return (actions - self.act_offset) / self.act_scale

  def obs_clip_fraction(self, obs):
    y = obs * self.obs_scale + self.obs_offset
    return jnp.mean((jnp.abs(y) > 1.0).astype(jnp.float32))


def _limits(x: np.ndarray, margin: float):
  lo, hi = x.min(0), x.max(0)
  span = hi - lo
  lo, hi = lo - margin * span, hi + margin * span
  flat = (hi - lo) < RANGE_EPS
  scale = np.where(flat, 1.0, 2.0 / np.where(flat, 1.0, hi - lo))
  offset = np.where(flat, -(lo + hi) / 2, -1.0 - scale * lo)
  return scale.astype(np.float32), offset.astype(np.float32)


def fit(
  obs: np.ndarray, actions: np.ndarray, margin: float = 0.1, identity_action_dims: slice | None = None
) -> Normalizer:
  """From all demonstration frames: obs (N, D), actions (N, A). `identity_action_dims` defaults to
  everything after the 3 position dims (rotation-6d and gripper of the absolute action)."""
  obs_scale, obs_offset = _limits(np.asarray(obs, np.float64), margin)
  act_scale, act_offset = _limits(np.asarray(actions, np.float64), margin)
  ident = identity_action_dims if identity_action_dims is not None else slice(3, None)
  act_scale[ident], act_offset[ident] = 1.0, 0.0
  return Normalizer(jnp.asarray(obs_scale), jnp.asarray(obs_offset), jnp.asarray(act_scale), jnp.asarray(act_offset))

"""Per-dimension limits normalisation (DESIGN.md, "Normalisation").

Low-dim observations map their range in the demonstrations, widened by a margin on each side (default
10% of the range), to [-1, 1]. Action positions map the spec's action box to [-1, 1]
(`policy.action_range = workspace`: the task's workspace, every position its demonstrator commands from
a thousand start states, widened) or, as before (`demonstrations`), their range in the demonstrations
widened by the same margin; rotation-6d and gripper action dims stay as they are (already in [-1, 1]). Each observation dimension's span has a floor from its quantity's physical
range (`obs_min_span`, e.g. `ManipulationEnv.obs_min_span`), so a dimension that barely moved in a few
demonstrations does not get a gain in the hundreds; an action dimension with (almost) no range is
only shifted to 0. Observations are not clipped after scaling: an off-distribution state stays
visibly out of range (`out_of_range_fraction` measures how much). Training targets are clipped to
[-1, 1] as the sampler clips its output; under the workspace box no target is outside (a fit refuses
one: `outside`), under the demonstrations' range the fit records the fraction clipped. Statistics come from the demonstrations once and are
stored with the parameters. (Diffusion Policy's low-dim code uses one global scale for observations;
that quirk is not copied.) An image policy's observations {"lowdim", "images"} have their low-dim
vector normalised so, and their uint8 images mapped to [0, 1] (Diffusion Policy's image scaling).
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
    """Raw policy observations (..., D), or {"lowdim": (..., D), "images": {key: (..., H, W, 3) uint8}}."""
    if isinstance(obs, dict):
      images = {k: v.astype(jnp.float32) / 255.0 for k, v in obs["images"].items()}
      return {"lowdim": self.normalize_obs(obs["lowdim"]), "images": images}
    return obs * self.obs_scale + self.obs_offset

  def unnormalize_obs(self, obs):
    """Normalised low-dim observations (..., D) -> raw."""
    return (obs - self.obs_offset) / self.obs_scale

  def normalize_actions(self, actions):
    return jnp.clip(actions * self.act_scale + self.act_offset, -1.0, 1.0)

  def unnormalize_actions(self, actions):
    return (actions - self.act_offset) / self.act_scale

  def outside(self, actions: np.ndarray, tol: float = 1e-5) -> np.ndarray:
    """Raw actions (..., A) -> (..., A) bool: where a normalised value is outside [-1, 1] (so training
    would clip it), in float64 on the host."""
    scale, offset = (np.asarray(x, np.float64) for x in (self.act_scale, self.act_offset))
    return np.abs(np.asarray(actions, np.float64) * scale + offset) > 1.0 + tol

  def out_of_range_fraction(self, obs, mask=None):
    """The fraction of normalised observation features outside [-1, 1] over raw obs (..., D), counting
    only the frames where `mask` (...) is set (default all); of an image policy's, the low-dim vector's."""
    obs = lowdim(obs)
    out = jnp.abs(self.normalize_obs(obs)) > 1.0
    if mask is None:
      return jnp.mean(out.astype(jnp.float32))
    mask = jnp.asarray(mask, jnp.float32)[..., None]
    return jnp.sum(out * mask) / jnp.maximum(jnp.sum(mask) * obs.shape[-1], 1.0)


def lowdim(obs):
  """The low-dim vector of policy observations in either form (`normalize_obs`)."""
  return obs["lowdim"] if isinstance(obs, dict) else obs


def _limits(x: np.ndarray, margin: float, min_span=None):
  lo, hi = x.min(0), x.max(0)
  span = hi - lo
  lo, hi = lo - margin * span, hi + margin * span
  if min_span is not None:  # widen around the centre to the floor
    centre, half = (lo + hi) / 2, np.maximum(hi - lo, min_span) / 2
    lo, hi = centre - half, centre + half
  flat = (hi - lo) < RANGE_EPS
  scale = np.where(flat, 1.0, 2.0 / np.where(flat, 1.0, hi - lo))
  offset = np.where(flat, -(lo + hi) / 2, -1.0 - scale * lo)
  return scale.astype(np.float32), offset.astype(np.float32)


def fit(
  obs: np.ndarray,
  actions: np.ndarray,
  margin: float = 0.1,
  obs_min_span: np.ndarray | None = None,
  num_robots: int = 1,
  action_box: tuple[np.ndarray, np.ndarray] | None = None,
  ranged: np.ndarray | None = None,
) -> Normalizer:
  """From all demonstration frames: obs (N, D), actions (N, A). `obs_min_span` (D,): the smallest span
  each observation dimension maps to [-1, 1] (none by default). The actions are `num_robots` equal
  blocks, each a position (its first 3 dims, normalised) and then rotation and gripper (kept as they
  are); `ranged` (A,) bool (`PolicySpec.ranged_action_dims`) names the normalised dims instead (a real
  gripper's opening in metres too). `action_box` (lo, hi), each (A,) (`PolicySpec.action_bounds`): the
  normalised dims it bounds map it to [-1, 1] instead of the data's widened range."""
  floor = None if obs_min_span is None else np.asarray(obs_min_span, np.float64)
  obs_scale, obs_offset = _limits(np.asarray(obs, np.float64), margin, floor)
  act_scale, act_offset = _limits(np.asarray(actions, np.float64), margin)
  if ranged is None:
    block = act_scale.shape[0] // num_robots
    ident = np.arange(act_scale.shape[0]) % block >= 3
  else:
    ident = ~np.asarray(ranged, bool)
  if action_box is not None:
    lo, hi = (np.asarray(x, np.float64) for x in action_box)
    boxed = ~ident & np.isfinite(lo) & np.isfinite(hi)
    lo, hi = lo[boxed], hi[boxed]
    act_scale[boxed], act_offset[boxed] = 2.0 / (hi - lo), -1.0 - 2.0 * lo / (hi - lo)
  act_scale[ident], act_offset[ident] = 1.0, 0.0
  return Normalizer(jnp.asarray(obs_scale), jnp.asarray(obs_offset), jnp.asarray(act_scale), jnp.asarray(act_offset))

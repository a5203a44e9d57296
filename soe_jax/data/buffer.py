"""Fixed-capacity episode buffer on device, and Diffusion Policy's window sampling.

Static shapes (capacity x max_length) keep aggregation and sampling jittable, so nothing recompiles as
rounds add episodes. Provenance per episode: `source` (0 = demonstration, r = exploration round r)
and `steered`.

Window sampling follows Diffusion Policy's SequenceSampler: with horizon T, n_obs_steps To and
n_action_steps Ta, an episode of length L has L - T + To + Ta - 1 windows (L - 7 for 16/2/8), starting
from -(To - 1); indices outside the episode repeat its first or last frame. Windows are drawn
uniformly over all windows of all valid episodes. A sample holds the first To observations and all T
actions of its window.

A re-fit may sample otherwise (`Sampling`): a fixed share of each batch from the demonstrations
(`demo_fraction`, the rest from the other episodes), and self-collected episodes' windows only where
they start at a recorded decision (`aligned`: the window's executed part, actions To-1 .. To-1+Ta-1,
is then one chunk as the policy sampled it, never two spliced; decisions every Ta steps from 0).

An image policy's buffer also holds every stored frame's camera images, uint8 and unpadded: episode i's
frames are `images[key][first_frame[i] : first_frame[i] + length[i]]` of a store of `image_frames`
frames (padding 2,048 episodes x 400 steps of two 84 x 84 cameras would take 35 GB); its windows'
observations are then {"lowdim": (B, To, D), "images": {key: (B, To, H, W, 3) uint8}}.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct


@struct.dataclass
class EpisodeBuffer:
  obs: jax.Array  # (N, L, D)
  actions: jax.Array  # (N, L, A)
  length: jax.Array  # (N,) int32
  valid: jax.Array  # (N,) bool
  source: jax.Array  # (N,) int32
  steered: jax.Array  # (N,) bool
  count: jax.Array  # () int32, episodes stored
  images: dict | None = None  # {key: (F, H, W, 3) uint8}, the stored frames' images in episode order
  first_frame: jax.Array | None = None  # (N,) int32, each episode's first frame in `images`

  @property
  def capacity(self) -> int:
    return self.obs.shape[0]

  @property
  def max_length(self) -> int:
    return self.obs.shape[1]


def create(capacity: int, max_length: int, obs_dim: int, action_dim: int) -> EpisodeBuffer:
  return EpisodeBuffer(
    obs=jnp.zeros((capacity, max_length, obs_dim)),
    actions=jnp.zeros((capacity, max_length, action_dim)),
    length=jnp.zeros(capacity, jnp.int32),
    valid=jnp.zeros(capacity, bool),
    source=jnp.zeros(capacity, jnp.int32),
    steered=jnp.zeros(capacity, bool),
    count=jnp.zeros((), jnp.int32),
  )


def with_images(buffer: EpisodeBuffer, images: list[dict], image_frames: int) -> EpisodeBuffer:
  """`buffer` with the camera images of its stored episodes, `images[i]` {key: (length_i, H, W, 3)
  uint8} for the i-th, in a store of `image_frames` frames."""
  lengths = np.asarray(jax.device_get(buffer.length))[: len(images)]
  if len(images) != int(buffer.count):
    raise ValueError(f"images of {len(images)} episodes for a buffer of {int(buffer.count)}")
  total = int(lengths.sum())
  if total > image_frames:
    raise ValueError(f"{total} frames of images do not fit in data.image_frames={image_frames}; raise it")
  keys = tuple(images[0]) if images else ()
  store = {}
  for k in keys:
    frames = np.zeros((image_frames,) + images[0][k].shape[1:], np.uint8)
    if total:
      frames[:total] = np.concatenate([ep[k] for ep in images])
    store[k] = jnp.asarray(frames)
  first = np.zeros(buffer.capacity, np.int32)
  first[: len(images)] = np.cumsum(lengths) - lengths
  return buffer.replace(images=store, first_frame=jnp.asarray(first))


def pad_episodes(episodes: list[dict], max_length: int, obs_key: str = "policy_obs") -> dict:
  """A list of {obs_key: (T, D), "actions": (T, A)} -> padded numpy arrays with lengths."""
  n = len(episodes)
  d = episodes[0][obs_key].shape[-1]
  a = episodes[0]["actions"].shape[-1]
  obs, actions = np.zeros((n, max_length, d), np.float32), np.zeros((n, max_length, a), np.float32)
  length = np.zeros(n, np.int32)
  for i, ep in enumerate(episodes):
    t = ep["actions"].shape[0]
    if t > max_length:
      raise ValueError(f"episode {i} has {t} steps, more than the buffer's max_length {max_length}")
    obs[i, :t], actions[i, :t], length[i] = ep[obs_key], ep["actions"], t
  return dict(obs=obs, actions=actions, length=length)


@jax.jit
def add(buffer: EpisodeBuffer, obs, actions, length, keep, source, steered=None) -> EpisodeBuffer:
  """Append the episodes with `keep` set (padded (M, L, .) arrays) after the stored ones. Episodes that
  do not fit in the capacity are dropped; compare `count` before and after to see how many landed."""
  m = obs.shape[0]
  steered = jnp.zeros(m, bool) if steered is None else steered
  order = jnp.argsort(~keep, stable=True)  # kept episodes first, in their order
  n_keep = jnp.sum(keep).astype(jnp.int32)
  slots = buffer.count + jnp.arange(m)
  ok = (jnp.arange(m) < n_keep) & (slots < buffer.capacity)
  slots = jnp.where(ok, slots, buffer.capacity)  # out of range: dropped by mode="drop"

  def put(dst, src):
    return dst.at[slots].set(src[order], mode="drop")

  source = jnp.broadcast_to(jnp.asarray(source, jnp.int32), (m,))
  return buffer.replace(
    obs=put(buffer.obs, obs),
    actions=put(buffer.actions, actions),
    length=put(buffer.length, length.astype(jnp.int32)),
    valid=buffer.valid.at[slots].set(True, mode="drop"),
    source=put(buffer.source, source),
    steered=put(buffer.steered, steered),
    count=jnp.minimum(buffer.count + n_keep, buffer.capacity),
  )


@dataclasses.dataclass(frozen=True)
class Sampling:
  """How a fit draws windows (`rounds.demo_fraction`, `rounds.aligned_windows`); the default is
  Diffusion Policy's uniform draw over every window."""

  demo_fraction: float = 0.0  # > 0: round(demo_fraction * B) of each batch from source-0 episodes
  aligned: bool = False  # self-collected episodes' windows start at decisions only


UNIFORM = Sampling()


def num_windows(
  buffer: EpisodeBuffer, horizon: int, n_obs_steps: int, n_action_steps: int, aligned: bool = False
) -> jax.Array:
  """(N,) windows per episode (0 for empty slots, at least 1 for a stored episode); `aligned`: a
  self-collected episode's only those starting at a decision."""
  w = buffer.length - horizon + n_obs_steps + n_action_steps - 1
  if aligned:
    at_decisions = (buffer.length - horizon + n_action_steps + n_obs_steps - 2) // n_action_steps + 1
    w = jnp.where(buffer.source != 0, at_decisions, w)
  return jnp.where(buffer.valid, jnp.maximum(w, 1), 0)


def _window(buffer, ep, j, horizon: int, n_obs_steps: int, n_action_steps: int, aligned: bool) -> dict:
  """Episode `ep`'s window number `j` (B,) each."""
  step = jnp.where(aligned & (buffer.source[ep] != 0), n_action_steps, 1) if aligned else 1
  start = j * step - (n_obs_steps - 1)
  idx = jnp.clip(start[:, None] + jnp.arange(horizon), 0, buffer.length[ep][:, None] - 1)
  obs = buffer.obs[ep[:, None], idx[:, :n_obs_steps]]
  if buffer.images is not None:
    frames = buffer.first_frame[ep][:, None] + idx[:, :n_obs_steps]
    obs = {"lowdim": obs, "images": {k: v[frames] for k, v in buffer.images.items()}}
  actions = buffer.actions[ep[:, None], idx]
  return {"obs": obs, "actions": actions}


def _locate(counts, u):
  """Window numbers `u` over `counts` (N,) -> (episode, number within it)."""
  cum = jnp.cumsum(counts)
  ep = jnp.searchsorted(cum, u, side="right")
  return ep, u - (cum[ep] - counts[ep])


def windows(
  buffer: EpisodeBuffer, u, horizon: int, n_obs_steps: int, n_action_steps: int, aligned: bool = False
) -> dict:
  """Windows number `u` (B,) of the buffer's `num_windows` in order (episode by episode) -> {"obs":
  (B, To, D) (with images: {"lowdim", "images"}), "actions": (B, T, A)}, raw (not normalised)."""
  counts = num_windows(buffer, horizon, n_obs_steps, n_action_steps, aligned)
  ep, j = _locate(counts, u)
  return _window(buffer, ep, j, horizon, n_obs_steps, n_action_steps, aligned)


def sample_windows(
  buffer: EpisodeBuffer,
  key,
  batch_size: int,
  horizon: int,
  n_obs_steps: int,
  n_action_steps: int,
  sampling: Sampling = UNIFORM,
) -> dict:
  """`batch_size` windows drawn uniformly from all of them (`windows`), or as `sampling` says: the
  first round(demo_fraction * B) from the demonstrations' windows, the others from the other
  episodes' (from the demonstrations' too while there are none)."""
  counts = num_windows(buffer, horizon, n_obs_steps, n_action_steps, sampling.aligned)
  if sampling.demo_fraction <= 0:
    u = jax.random.randint(key, (batch_size,), 0, jnp.sum(counts))
    return _window(buffer, *_locate(counts, u), horizon, n_obs_steps, n_action_steps, sampling.aligned)
  n_demo = int(round(sampling.demo_fraction * batch_size))
  demo = jnp.where(buffer.source == 0, counts, 0)
  other = counts - demo
  other = jnp.where(jnp.sum(other) > 0, other, demo)
  key_demo, key_other = jax.random.split(key)
  u_demo = jax.random.randint(key_demo, (n_demo,), 0, jnp.sum(demo))
  u_other = jax.random.randint(key_other, (batch_size - n_demo,), 0, jnp.sum(other))
  (ep_d, j_d), (ep_o, j_o) = _locate(demo, u_demo), _locate(other, u_other)
  ep, j = jnp.concatenate([ep_d, ep_o]), jnp.concatenate([j_d, j_o])
  return _window(buffer, ep, j, horizon, n_obs_steps, n_action_steps, sampling.aligned)

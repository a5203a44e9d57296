"""Episodes between their three forms: padded batches (rollouts, demonstrations), lists of episodes
(what HDF5 files hold: {"obs": {key: (T, .)}, "next_obs" {key: (T, .)}, "actions" (T, A), "states"
(T, 1 + nq + nv) float64 [time, qpos, qvel], "success"}), and the fixed-capacity training buffer.

An `EpisodeSet` is one group of episodes with its provenance: `source` 0 for demonstrations, r for
exploration round r, and `steered` for episodes a person steered on the steering page.
"""

from __future__ import annotations

from typing import NamedTuple

import ml_collections
import numpy as np

from soe_jax.data import buffer as buffer_lib


class EpisodeSet(NamedTuple):
  episodes: list[dict]
  source: int
  steered: bool = False


def from_batch(obs: dict, actions, states, length, success, mask=None, next_obs: dict | None = None) -> list[dict]:
  """Padded arrays (N, H, ...) with lengths (N,) -> the episodes where `mask` (N,) is set (default all),
  trimmed to their lengths."""
  keep = np.ones(len(length), bool) if mask is None else np.asarray(mask, bool)
  out = []
  for i in np.flatnonzero(keep):
    t = int(length[i])
    ep = dict(obs={k: v[i, :t] for k, v in obs.items()}, actions=actions[i, :t], states=states[i, :t])
    if next_obs is not None:
      ep["next_obs"] = {k: v[i, :t] for k, v in next_obs.items()}
    out.append(dict(ep, success=bool(success[i])))
  return out


def draw_images(env, episodes: list[dict], keys: tuple[str, ...]) -> list[dict]:
  """Each episode's camera images `keys` at its states (the task's renderer, `env.draw`), put into
  its `obs` where it lacks them (a file's own images stay) -> the same episodes. All frames are drawn
  in one batch, spread over the renderer's processes."""
  todo = [ep for ep in episodes if any(k not in ep["obs"] for k in keys)]
  if not todo:
    return episodes
  if env is None:
    raise ValueError(f"episodes without the images {', '.join(keys)}, and no task (env=...) to draw them")
  if any("states" not in ep for ep in todo):
    raise ValueError("an episode without simulator states has no images to draw; image policies need states")
  nq = env.mj_model.nq
  # In float32, as a step draws its observation from the state's float32 qpos: the same pixels (the
  # float64 pose can turn a pixel at an edge).
  qpos = np.concatenate([np.asarray(ep["states"])[:, 1 : 1 + nq] for ep in todo]).astype(np.float32)
  drawn = env.draw(qpos)
  start = 0
  for ep in todo:
    t = len(ep["states"])
    for k in keys:
      ep["obs"].setdefault(k, drawn[k][start : start + t])
    start += t
  return episodes


def policy_episode(ep: dict, keys: tuple[str, ...]) -> dict:
  """An episode -> {"policy_obs" (T, D): the low-dim observations `keys` (a spec's `lowdim_keys`, a
  policy's) concatenated in that order, "actions" (T, A)} for the buffer."""
  missing = [k for k in keys if k not in ep["obs"]]
  if missing:
    raise KeyError(f"the episode has no observation {', '.join(missing)} (it has {', '.join(ep['obs'])})")
  parts = [np.asarray(ep["obs"][k], np.float32).reshape(len(ep["actions"]), -1) for k in keys]
  return {"policy_obs": np.concatenate(parts, -1), "actions": np.asarray(ep["actions"], np.float32)}


def policy_frames(episodes: list[dict], keys: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
  """All frames of `episodes`: (policy observations (N, D), actions (N, A)), e.g. for the normaliser."""
  flat = [policy_episode(e, keys) for e in episodes]
  return np.concatenate([e["policy_obs"] for e in flat]), np.concatenate([e["actions"] for e in flat])


def decisions(ep: dict, keys: tuple[str, ...], n_obs_steps: int, n_action_steps: int):
  """An episode's decisions (every Ta steps from 0): their steps (N,), the observation histories the
  policy saw there (N, To, D; the first frame repeated before the start) and the executed actions
  recorded from each (N, Ta, A; the last repeated past the end)."""
  flat = policy_episode(ep, keys)
  obs, actions = flat["policy_obs"], flat["actions"]
  t = np.arange(0, len(actions), n_action_steps)
  hists = obs[np.clip(t[:, None] + np.arange(-n_obs_steps + 1, 1), 0, len(obs) - 1)]
  return t, hists, actions[np.clip(t[:, None] + np.arange(n_action_steps), 0, len(actions) - 1)]


def policy_windows(episodes: list[dict], policy) -> dict:
  """Every training window of `episodes` in order, as the fit samples them for `policy`
  (`buffer.windows`): {"obs": (N, To, D) low-dim, "actions": (N, T, A)} raw."""
  horizon, n_obs_steps, n_action_steps = policy.horizon, policy.n_obs_steps, policy.n_action_steps
  flat = [policy_episode(e, policy.lowdim_keys) for e in episodes]
  longest = max(len(e["actions"]) for e in flat)
  buf = buffer_lib.create(len(flat), longest, flat[0]["policy_obs"].shape[-1], flat[0]["actions"].shape[-1])
  p = buffer_lib.pad_episodes(flat, longest)
  buf = buffer_lib.add(buf, p["obs"], p["actions"], p["length"], np.ones(len(flat), bool), 0)
  total = int(np.sum(buffer_lib.num_windows(buf, horizon, n_obs_steps, n_action_steps)))
  out = buffer_lib.windows(buf, np.arange(total), horizon, n_obs_steps, n_action_steps)
  return {k: np.asarray(v) for k, v in out.items()}


def build_buffer(
  config: ml_collections.ConfigDict, policy, sets: list[EpisodeSet], env=None
) -> buffer_lib.EpisodeBuffer:
  """A buffer of `config.data.capacity` episodes of at most `config.data.max_length` steps holding `sets`;
  for an image policy with its episodes' images too (`config.data.image_frames` frames of them, drawn
  by `env`'s renderer where an episode lacks them, and kept in the episode: `draw_images`)."""
  buf = buffer_lib.create(int(config.data.capacity), int(config.data.max_length), policy.obs_dim, policy.action_dim)
  total = sum(len(s.episodes) for s in sets)
  if total > buf.capacity:
    raise ValueError(f"{total} episodes do not fit in data.capacity={buf.capacity}; raise it")
  for s in sets:
    if s.episodes:
      n = len(s.episodes)
      p = buffer_lib.pad_episodes([policy_episode(e, policy.lowdim_keys) for e in s.episodes], buf.max_length)
      buf = buffer_lib.add(buf, p["obs"], p["actions"], p["length"], np.ones(n, bool), s.source, np.full(n, s.steered))
  if policy.image_keys:
    stored = [ep for s in sets for ep in s.episodes]
    draw_images(env, stored, policy.image_keys)
    images = [{k: np.asarray(ep["obs"][k], np.uint8) for k in policy.image_keys} for ep in stored]
    buf = buffer_lib.with_images(buf, images, int(config.data.image_frames))
  return buf

"""Episodes in Diffusion Policy's zarr replay-buffer layout, written and read back exactly.

Diffusion Policy's `ReplayBuffer` (real-stanford/diffusion_policy, `diffusion_policy/common/
replay_buffer.py`) opens a zarr group with `data/<key>`, arrays whose first axis is time, all
episodes concatenated, and `meta/episode_ends` (int64, the cumulative episode lengths); its
constructor asserts that every `data` array is `episode_ends[-1]` long. It is written in zarr's
format 2, which the zarr 2 that Diffusion Policy pins reads.

Written here: `data/action` (T, A) float32, `data/<obs key>` (T, d) per observation key,
`data/next_<obs key>` the observation after each action, `data/state` (T, 1 + nq + nv) float64
where the episodes have states; `meta/episode_ends`, and per episode `meta/episode_source` (0 for
demonstrations, r for round r's exploration), `meta/episode_steered` and `meta/episode_success`
(extra `meta` arrays, which the replay buffer carries along); the root's attribute `soe_jax` holds
the writer's metadata. Needs the `zarr` extra (`pip install -e ".[zarr]"`, zarr >= 3).
"""

from __future__ import annotations

import os

import numpy as np

from soe_jax.data.episodes import EpisodeSet
from soe_jax.runtime import atomic
from soe_jax.runtime.errors import UserError


def _zarr():
  try:
    import zarr
  except ImportError:
    raise UserError('the zarr format needs the zarr extra: pip install -e ".[zarr]"') from None
  return zarr


def write(path: str, sets: list[EpisodeSet], meta: dict) -> None:
  """Write the episodes of `sets`, in order, to the zarr group at `path` (replacing it)."""
  zarr = _zarr()
  episodes = [ep for s in sets for ep in s.episodes]
  if not episodes:
    raise ValueError("no episodes to write")
  with atomic.replacing(path) as tmp:
    _write(zarr.open_group(tmp, mode="w", zarr_format=2), sets, episodes, meta)


def _write(root, sets, episodes, meta) -> None:
  data, m = root.require_group("data"), root.require_group("meta")
  cat = lambda f: np.concatenate([np.asarray(f(ep)) for ep in episodes])
  data.create_array("action", data=cat(lambda ep: np.asarray(ep["actions"], np.float32)))
  for key in episodes[0]["obs"]:
    data.create_array(key, data=cat(lambda ep: ep["obs"][key]))
    data.create_array(f"next_{key}", data=cat(lambda ep: ep["next_obs"][key]))
  if all("states" in ep for ep in episodes):
    data.create_array("state", data=cat(lambda ep: ep["states"]))
  m.create_array("episode_ends", data=np.cumsum([len(ep["actions"]) for ep in episodes]).astype(np.int64))
  m.create_array("episode_source", data=np.asarray([s.source for s in sets for _ in s.episodes], np.int64))
  m.create_array("episode_steered", data=np.asarray([s.steered for s in sets for _ in s.episodes], bool))
  m.create_array("episode_success", data=np.asarray([ep.get("success", True) for ep in episodes], bool))
  root.attrs["soe_jax"] = meta


def read(path: str) -> tuple[list[EpisodeSet], dict]:
  """The episodes of a zarr group in this layout -> (their sets by source and steering, in order of
  first appearance; the writer's metadata). A store that cannot be read (not a zarr group, damaged
  metadata or chunks, arrays of the wrong lengths) is a `ValueError` naming it."""
  zarr = _zarr()
  if not os.path.exists(path):
    raise FileNotFoundError(f"zarr store {path!r} does not exist")
  try:
    root = zarr.open_group(path, mode="r")
  except Exception as e:  # zarr's errors differ between versions and stores
    raise ValueError(
      f"zarr store {path!r} is not a zarr group (not Diffusion Policy's replay-buffer layout): {e}"
    ) from e
  try:
    return _read(path, root)
  except ValueError:
    raise
  except Exception as e:  # a damaged chunk or metadata: numcodecs', zarr's or numpy's errors
    raise ValueError(f"zarr store {path!r} is damaged: {type(e).__name__}: {e}") from e


def _read(path: str, root) -> tuple[list[EpisodeSet], dict]:
  for group, key in (("meta", "episode_ends"), ("data", "action")):
    if group not in root or key not in root[group]:
      raise ValueError(f"zarr store {path!r} has no {group}/{key} (not Diffusion Policy's replay-buffer layout)")
  data, m = root["data"], root["meta"]
  ends = np.asarray(m["episode_ends"][:])
  starts = np.concatenate([[0], ends[:-1]])
  arrays = {k: np.asarray(data[k][:]) for k in data.keys()}
  obs_keys = [k for k in arrays if k not in ("action", "state") and not k.startswith("next_")]
  n = len(ends)
  if n == 0 or any(len(v) != ends[-1] for v in arrays.values()) or np.any(np.diff(starts) < 0):
    raise ValueError(
      f"zarr store {path!r}: its data arrays are not all meta/episode_ends[-1] long, or it has no episodes"
    )
  source = np.asarray(m["episode_source"][:]) if "episode_source" in m else np.zeros(n, np.int64)
  steered = np.asarray(m["episode_steered"][:]) if "episode_steered" in m else np.zeros(n, bool)
  success = np.asarray(m["episode_success"][:]) if "episode_success" in m else np.ones(n, bool)
  sets: dict[tuple, list] = {}
  for i, (a, b) in enumerate(zip(starts, ends)):
    ep = dict(obs={k: arrays[k][a:b] for k in obs_keys}, actions=arrays["action"][a:b], success=bool(success[i]))
    if all(f"next_{k}" in arrays for k in obs_keys):
      ep["next_obs"] = {k: arrays[f"next_{k}"][a:b] for k in obs_keys}
    if "state" in arrays:
      ep["states"] = arrays["state"][a:b]
    sets.setdefault((int(source[i]), bool(steered[i])), []).append(ep)
  return [EpisodeSet(eps, src, st) for (src, st), eps in sets.items()], dict(root.attrs.get("soe_jax", {}))

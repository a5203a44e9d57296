"""Groups of episodes (`EpisodeSet`s, such as the data a run's fit trained on: `RunDir.fit_sets`,
`python -m soe_jax export`) in another codebase's format, and read back. Formats:
- `robomimic`: one HDF5 file (`soe_jax/data/hdf5.py`), the episodes in that order, with a filter key
  per group: `demos`, `round_<r>`, `steered_<r>` (robomimic's `filter_by_attribute` takes one); an
  image run's episodes with robomimic's image keys too (`agentview_image`, `robot0_eye_in_hand_image`,
  uint8 (T, 84, 84, 3)), drawn from their states as the run's policy saw them;
- `zarr`: Diffusion Policy's replay buffer (`soe_jax/data/zarr_store.py`), each episode's group in
  `meta/episode_source` and `meta/episode_steered`;
- `rlds`: an RLDS dataset through tensorflow-datasets (`soe_jax/data/rlds.py`), each episode's group in
  its `episode_metadata`;
- `lerobot` (pyarrow: the `robot` extra): a LeRobotDataset v3.0 (`soe_jax/data/lerobot.py`) at the control
  rate, every observation `observation.<key>` (cameras as videos), `next.success` from each episode's
  success, and per frame the episode's group (`source`, `steered`), the simulator state
  (`simulator_state`, float64) and the episode's start state (`start_state`, so
  `refit.select=first_success` can group tries), as a robot's recorder would write it; the provenance in
  `meta/soe_jax.json`. (No next observations: LeRobot keeps none.)
`load(path)` reads any back as the same groups of episodes (`EpisodeSet`s), so a buffer built
from them holds the same windows (a LeRobotDataset's images within its video's PSNR).
"""

from __future__ import annotations

import os
import re

import h5py
import ml_collections
import numpy as np

from soe_jax.data import hdf5, rlds, zarr_store
from soe_jax.data.episodes import EpisodeSet, draw_images
from soe_jax.envs import registry as env_registry
from soe_jax.runtime import atomic
from soe_jax.runtime.errors import UserError

FORMATS = ("robomimic", "zarr", "rlds", "lerobot")
PREFIX = "observation."  # a LeRobotDataset's observation features
CONTROL_HZ = 20  # the simulated tasks' control rate (envs.controller.CONTROL_DT)
PROVENANCE = "soe_jax.json"  # beside LeRobot's own metadata


def group_name(s: EpisodeSet) -> str:
  """The filter key of a group: demos, round_<r>, steered_<r>."""
  return "demos" if s.source == 0 and not s.steered else f"{'steered' if s.steered else 'round'}_{s.source}"


def write_robomimic(path: str, sets: list[EpisodeSet], meta: dict) -> None:
  episodes, masks, start = [], {}, 0
  for s in sets:
    masks.setdefault(group_name(s), []).extend(range(start, start + len(s.episodes)))
    episodes += s.episodes
    start += len(s.episodes)
  hdf5.write_episodes(path, episodes, meta, masks)


def _meta(env_args: dict) -> dict:
  """The writer's metadata back from robomimic's `env_args` (a file written elsewhere: `env_args`)."""
  if "soe_jax" not in env_args:
    return env_args
  return dict(env_args["soe_jax"], env_kwargs=env_args.get("env_kwargs", {}))


def read_robomimic(path: str) -> tuple[list[EpisodeSet], dict]:
  """A file with this exporter's filter keys -> its groups; any other file -> one group of all its
  episodes, as demonstrations."""
  try:
    with h5py.File(path, "r") as f:
      keys = sorted(f["mask"].keys()) if "mask" in f else []
  except FileNotFoundError:
    raise
  except OSError as e:
    raise ValueError(f"{path!r} is not a readable HDF5 file: {e}") from None
  except (KeyError, RuntimeError) as e:
    raise ValueError(f"{path!r} is damaged: {type(e).__name__}: {e}") from None
  groups = [k for k in keys if k == "demos" or re.fullmatch(r"(round|steered)_\d+", k)]
  if not groups:
    episodes, env_args = hdf5.read_episodes(path)
    return [EpisodeSet(episodes, 0)], _meta(env_args)
  order = lambda k: (("demos", "round", "steered").index(k.split("_")[0]), int(k.split("_")[-1]) if "_" in k else 0)
  sets = []
  for key in sorted(groups, key=order):
    episodes, env_args = hdf5.read_episodes(path, filter_key=key)
    source = 0 if key == "demos" else int(key.split("_")[1])
    sets.append(EpisodeSet(episodes, source, key.startswith("steered")))
  return sets, _meta(env_args)


def _lerobot():
  """`soe_jax/data/lerobot.py`, imported only where a LeRobotDataset is read or written: it needs pyarrow,
  which the `robot` extra installs and the base install lacks (robomimic's HDF5 needs none of it)."""
  try:
    from soe_jax.data import lerobot
  except ImportError as e:
    if (e.name or "").partition(".")[0] != "pyarrow":
      raise
    raise UserError('the lerobot format needs pyarrow, in the robot extra: pip install -e ".[robot]"') from None
  return lerobot


def write_lerobot(path: str, sets: list[EpisodeSet], meta: dict) -> None:
  lerobot = _lerobot()
  episodes = []
  for s in sets:
    for ep in s.episodes:
      t = len(ep["actions"])
      columns = {"source": np.full(t, s.source, np.int64), "steered": np.full(t, s.steered, bool)}
      if "states" in ep:
        columns["simulator_state"] = np.asarray(ep["states"], np.float64)
        columns["start_state"] = np.repeat(columns["simulator_state"][:1], t, axis=0)
      obs = {PREFIX + k: np.asarray(v) for k, v in ep["obs"].items()}
      episodes.append(dict(obs=obs, actions=ep["actions"], success=bool(ep.get("success", True)), columns=columns))
  lerobot.write_dataset(path, episodes, CONTROL_HZ, robot_type=f"soe_jax {meta.get('env_name', '')}".strip())
  atomic.write_json(os.path.join(path, "meta", PROVENANCE), meta)


def read_lerobot(path: str) -> tuple[list[EpisodeSet], dict]:
  """A LeRobotDataset -> its groups (by the `source` and `steered` columns where it has them, else one
  group of demonstrations), observations under their keys without `observation.`."""
  info, found = _lerobot().read_dataset(path)
  groups = {}
  for ep in found:
    c = ep["columns"]
    key = (int(c["source"][0]), bool(c["steered"][0])) if "source" in c else (0, False)
    obs = {k[len(PREFIX) :] if k.startswith(PREFIX) else k: v for k, v in ep["obs"].items()}
    out = dict(obs=obs, actions=ep["actions"], success=bool(ep["success"]))
    if "simulator_state" in c:
      out["states"] = c["simulator_state"]
    groups.setdefault(key, []).append(out)
  provenance = os.path.join(path, "meta", PROVENANCE)
  meta = atomic.read_json(provenance) if os.path.exists(provenance) else {"lerobot_info": info}
  return [EpisodeSet(eps, src, steered) for (src, steered), eps in groups.items()], meta  # (in the written order)


def write(out: str, fmt: str, sets: list[EpisodeSet], meta: dict) -> None:
  """Write the groups `sets` with `meta` (`env_name`, `env_kwargs`, provenance) to `out` in format
  `fmt`; an image task's episodes get robomimic's image keys, drawn from their states."""
  if fmt not in FORMATS:
    raise UserError(f"unknown format {fmt!r}; known formats: {', '.join(FORMATS)}")
  if fmt == "robomimic" and meta["env_kwargs"].get("obs_mode") == "image":
    env = env_registry.env_from_config(ml_collections.ConfigDict(dict(meta["env_kwargs"], backend="mujoco")))
    draw_images(env, [ep for s in sets for ep in s.episodes], env.image_keys)
  writers = {"robomimic": write_robomimic, "zarr": zarr_store.write, "rlds": rlds.write, "lerobot": write_lerobot}
  writers[fmt](out, sets, meta)


def load(path: str) -> tuple[list[EpisodeSet], dict]:
  """Read an exported file or directory back (the format from what is there: an RLDS dataset, a zarr
  group or an HDF5 file)."""
  if os.path.isdir(os.path.join(path, rlds.NAME)):
    return rlds.read(path)
  if os.path.exists(os.path.join(path, "meta", "info.json")):
    return read_lerobot(path)
  if os.path.isdir(path):
    return zarr_store.read(path)
  if not os.path.exists(path):
    raise FileNotFoundError(f"{path!r} does not exist")
  return read_robomimic(path)

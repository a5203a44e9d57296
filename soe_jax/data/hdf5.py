"""Episodes in robomimic's HDF5 layout, written so that robomimic's own readers take them, and read
back exactly (robomimic's own files included).

What robomimic reads (ARISE-Initiative/robomimic at d309eae):
- `data` group, attribute `env_args`: JSON with `env_name`, `type` (an integer of `EnvType`:
  1 robosuite, 2 gym, 3 iGibson; `robomimic/envs/env_base.py` lines 9-16) and `env_kwargs` (a dict),
  `robomimic/utils/file_utils.py` lines 89-118 (`get_env_metadata_from_dataset`); attribute `total`,
  the number of samples.
- `data/demo_<i>`: the episodes, named so that robomimic sorts them by the integer after `demo_`
  (`robomimic/utils/dataset.py` line 204); attribute `num_samples` (T) (dataset.py line 221);
  `obs/<key>` (T, ...) and `next_obs/<key>` (T, ...) per observation key (dataset.py lines 320-322,
  `load_next_obs` on by default); `actions`, `rewards`, `dones` read with `.astype('float32')`,
  a missing one read as zeros (dataset.py lines 324-328); `states` (T, 1 + nq + nv), MuJoCo's state
  flattened as robosuite's `MjSimState.flatten`: [time, qpos, qvel] (robosuite
  `robosuite/utils/binding_utils.py`, `MjSimState`), which `robomimic/scripts/playback_dataset.py`
  (lines 285-288) loads one by one; an optional attribute `model_file` (the scene's MJCF).
- `mask/<filter key>`: an array of episode names as bytes (`dtype='S'`), written by
  `file_utils.create_hdf5_filter_key` (lines 60-63) and read by `get_demos_for_filter_key` (line 84)
  and the dataset's `filter_by_attribute` (dataset.py line 199), e.g. robomimic's `core_20` and
  SIME's `train_0.5`.

Written here: all of the above but `model_file` (the scenes are this project's, not robosuite's);
`env_args` = {env_name: robosuite's name for the task, type: 1, env_kwargs: the task's config where
the writer has it, soe_jax: the writer's metadata (task, source, round, strategy, ...)}; `rewards` 1
and `dones` 1 at the last step of a successful episode (robomimic's sparse reward), else 0; `states`
as given (float64 [time, qpos, qvel] from this project's rollouts and demonstrations, bit for bit
the C engine's).

An episode is a dict: `obs` {key: (T, d) float32}, `actions` (T, A) float32, and optionally
`next_obs` {key: (T, d)} (an episode without it, e.g. from a file written before it was recorded,
is written with each step's next observation the following step's, the last one repeated),
`states` and `success` (written as the last step's `dones`; read back from it).
"""

from __future__ import annotations

import json
import os

import h5py
import numpy as np

from soe_jax.runtime import atomic
from soe_jax.runtime.errors import UserError

ROBOSUITE_TYPE = 1  # robomimic's EnvType.ROBOSUITE_TYPE
# robosuite's names of the tasks rebuilt here.
ROBOSUITE_NAMES = {"lift": "Lift", "can": "PickPlaceCan", "square": "NutAssemblySquare", "transport": "TwoArmTransport"}


def robomimic_env_args(meta: dict) -> dict:
  """robomimic's `env_args` for a file whose writer says `meta` ({env_name: the task, env_kwargs: its
  config (optional), ...}): robosuite's name and type, the kwargs, and `meta` under `soe_jax`."""
  meta = dict(meta)
  kwargs = meta.pop("env_kwargs", {})
  task = meta.get("env_name", "")
  return dict(env_name=ROBOSUITE_NAMES.get(task, task), type=ROBOSUITE_TYPE, env_kwargs=kwargs, soe_jax=meta)


def _next_obs(ep: dict) -> dict:
  if "next_obs" in ep:
    return ep["next_obs"]
  return {k: np.concatenate([v[1:], v[-1:]]) for k, v in ep["obs"].items()}


def write_episodes(path: str, episodes: list[dict], meta: dict, masks: dict[str, list[int]] | None = None) -> None:
  """Write `episodes` to `path` atomically (a temporary file, then a rename); `meta` goes into
  `env_args` (`robomimic_env_args`), `masks` {filter key: episode indices} into `mask/`."""
  os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
  for key, indices in (masks or {}).items():
    if any(not 0 <= i < len(episodes) for i in indices):
      raise ValueError(f"mask {key!r} names episodes outside 0..{len(episodes) - 1}: {sorted(indices)}")
  with atomic.replacing(path) as tmp, h5py.File(tmp, "w") as f:
    data = f.create_group("data")
    total = 0
    for i, ep in enumerate(episodes):
      actions = np.asarray(ep["actions"], np.float32)
      t = actions.shape[0]
      g = data.create_group(f"demo_{i}")
      g.attrs["num_samples"] = t
      g.create_dataset("actions", data=actions)
      rewards = np.zeros(t, np.float32)
      dones = np.zeros(t, np.int64)
      if ep.get("success", True):
        rewards[-1], dones[-1] = 1.0, 1
      g.create_dataset("rewards", data=rewards)
      g.create_dataset("dones", data=dones)
      if "states" in ep:
        g.create_dataset("states", data=np.asarray(ep["states"]))
      for group, obs in (("obs", ep["obs"]), ("next_obs", _next_obs(ep))):
        out = g.create_group(group)
        for key, value in obs.items():
          value = np.asarray(value)
          if value.shape[0] != t:
            raise ValueError(f"episode {i}: {group}[{key!r}] has {value.shape[0]} steps, actions have {t}")
          out.create_dataset(key, data=value)
      total += t
    data.attrs["total"] = total
    data.attrs["env_args"] = json.dumps(robomimic_env_args(meta))
    for key, indices in (masks or {}).items():
      f[f"mask/{key}"] = np.array([f"demo_{i}" for i in sorted(indices)], dtype="S")


def read_episodes(path: str, env=None, filter_key: str = "") -> tuple[list[dict], dict]:
  """Read a robomimic-layout file -> (episodes in `demo_i` index order, env_args); with `filter_key`,
  only the episodes its mask names (robomimic's `filter_by_attribute`).

  With `env` (the task, a `ManipulationEnv`), each episode's quaternion observations are put in the
  task's sign convention (`ManipulationEnv.conform_quaternions`: the hand's hemisphere, objects
  continuous from w >= 0, object-in-eef as conj(hand) * object), so a file written elsewhere, e.g.
  by robosuite with w >= 0 throughout, reads as this project's observations; files written here come
  back unchanged."""
  if not os.path.exists(path):
    raise FileNotFoundError(f"demonstration file {path!r} does not exist")
  try:
    f = h5py.File(path, "r")
  except OSError as e:
    raise UserError(f"demonstration file {path!r} is not a readable HDF5 file: {e}") from None
  try:
    with f:
      return _read(f, path, env, filter_key)
  except (KeyError, RuntimeError, OSError, TypeError, json.JSONDecodeError) as e:  # a file damaged inside
    raise UserError(f"demonstration file {path!r} is damaged: {type(e).__name__}: {e}") from None


def _read(f, path: str, env, filter_key: str) -> tuple[list[dict], dict]:
  if "data" not in f:
    raise UserError(f"demonstration file {path!r} has no 'data' group (not robomimic's layout)")
  data = f["data"]
  env_args = json.loads(data.attrs.get("env_args", "{}"))
  names = [k for k in data.keys() if k.startswith("demo_")]
  if filter_key:
    known = sorted(f["mask"].keys()) if "mask" in f else []
    if filter_key not in known:
      raise UserError(
        f"demonstration file {path!r} has no filter key {filter_key!r}; its filter keys: {', '.join(known) or 'none'}"
      )
    names = [n.decode("utf-8") for n in np.array(f[f"mask/{filter_key}"][:])]
    missing = [n for n in names if n not in data]
    if missing:
      raise UserError(f"demonstration file {path!r}: mask {filter_key!r} names missing episodes {missing[:5]}")
  names = sorted(names, key=lambda k: int(k.split("_")[1]))
  episodes = []
  for name in names:
    g = data[name]
    for required in ("actions", "obs"):
      if required not in g:
        raise UserError(f"demonstration file {path!r}: {name} has no {required!r}")
    ep = {"actions": g["actions"][()], "obs": {k: g["obs"][k][()] for k in g["obs"].keys()}}
    if "next_obs" in g:
      ep["next_obs"] = {k: g["next_obs"][k][()] for k in g["next_obs"].keys()}
    if "states" in g:
      ep["states"] = g["states"][()]
    if "dones" in g and len(g["dones"]):
      ep["success"] = bool(g["dones"][-1])  # as written above: done at the last step means success
    if env is not None:
      missing = [k for k in ("robot0_eef_quat", "object") if k not in ep["obs"]]
      if missing:
        raise UserError(f"demonstration file {path!r}: {name} has no obs {', '.join(missing)}")
      if set(ep.get("next_obs", {})) >= set(ep["obs"]):  # one sequence: obs, then the last next_obs
        full = env.conform_quaternions({k: np.concatenate([v, ep["next_obs"][k][-1:]]) for k, v in ep["obs"].items()})
        ep["obs"], ep["next_obs"] = {k: v[:-1] for k, v in full.items()}, {k: v[1:] for k, v in full.items()}
      else:
        ep["obs"] = env.conform_quaternions(ep["obs"])
        ep.pop("next_obs", None)
    episodes.append(ep)
  return episodes, env_args

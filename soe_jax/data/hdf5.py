"""Episodes in robomimic's HDF5 layout, written and read back exactly.

Layout (as robomimic's datasets): `data/` with attributes `total` (number of samples) and `env_args`
(JSON); one group `data/demo_i` per episode with attribute `num_samples`, datasets `actions` (T, A),
`obs/<key>` (T, d), `rewards` (T,), `dones` (T,), and `states` (T, nq) (here: joint positions of the
whole scene; robomimic stores MuJoCo's flattened state). `mask/` is left out.

An episode is a dict: `obs` {key: (T, d) float32}, `actions` (T, A) float32, and optionally `states`
and `success` (written as the last step's `dones`; read back from it).
"""

from __future__ import annotations

import json
import os

import h5py
import numpy as np


def write_episodes(path: str, episodes: list[dict], env_args: dict) -> None:
  """Write `episodes` to `path` atomically (a temporary file, then a rename)."""
  tmp = f"{path}.tmp-{os.getpid()}"
  os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
  with h5py.File(tmp, "w") as f:
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
      obs = g.create_group("obs")
      for key, value in ep["obs"].items():
        value = np.asarray(value)
        if value.shape[0] != t:
          raise ValueError(f"episode {i}: obs[{key!r}] has {value.shape[0]} steps, actions have {t}")
        obs.create_dataset(key, data=value)
      total += t
    data.attrs["total"] = total
    data.attrs["env_args"] = json.dumps(env_args)
  os.replace(tmp, path)


def read_episodes(path: str, env=None) -> tuple[list[dict], dict]:
  """Read a robomimic-layout file -> (episodes in `demo_i` index order, env_args).

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
    raise ValueError(f"demonstration file {path!r} is not a readable HDF5 file: {e}") from e
  with f:
    if "data" not in f:
      raise ValueError(f"demonstration file {path!r} has no 'data' group (not robomimic's layout)")
    data = f["data"]
    env_args = json.loads(data.attrs.get("env_args", "{}"))
    names = sorted((k for k in data.keys() if k.startswith("demo_")), key=lambda k: int(k.split("_")[1]))
    episodes = []
    for name in names:
      g = data[name]
      for required in ("actions", "obs"):
        if required not in g:
          raise ValueError(f"demonstration file {path!r}: {name} has no {required!r}")
      ep = {"actions": g["actions"][()], "obs": {k: g["obs"][k][()] for k in g["obs"].keys()}}
      if "states" in g:
        ep["states"] = g["states"][()]
      if "dones" in g and len(g["dones"]):
        ep["success"] = bool(g["dones"][-1])  # as written above: done at the last step means success
      if env is not None:
        missing = [k for k in ("robot0_eef_quat", "object") if k not in ep["obs"]]
        if missing:
          raise ValueError(f"demonstration file {path!r}: {name} has no obs {', '.join(missing)}")
        ep["obs"] = env.conform_quaternions(ep["obs"])
      episodes.append(ep)
  return episodes, env_args

"""What a data file holds (`python -m soe_jax inspect PATH`).

PATH: a robomimic HDF5 file (this project's demonstrations, a round's kept episodes, an export, or
robomimic's own), or an exported zarr store, RLDS dataset or LeRobotDataset. Prints the episodes per
group (filter key, or source round), their lengths, every key with its shape and dtype, and the
provenance the file records.
"""

from __future__ import annotations

import json
import os

import h5py
import numpy as np

from soe_jax.data import export
from soe_jax.runtime.errors import UserError


def _leaves(ep: dict, prefix: str = ""):
  for k, v in ep.items():
    if isinstance(v, dict):
      yield from _leaves(v, f"{prefix}{k}/")
    elif isinstance(v, np.ndarray):
      yield f"{prefix}{k}", v


def describe(path: str) -> str:
  """The lines `python -m soe_jax inspect PATH` prints."""
  if not os.path.exists(path):
    raise UserError(f"{path!r} does not exist")
  sets, meta = export.load(path)
  episodes = [ep for s in sets for ep in s.episodes]
  if not episodes:
    return f"{path}: no episodes\n"
  lengths = np.array([len(ep["actions"]) for ep in episodes])
  lines = [
    f"{path}: {len(episodes)} episodes, {lengths.sum()} steps; length min {lengths.min()} / mean "
    f"{lengths.mean():.1f} / max {lengths.max()}; successful {sum(ep.get('success', True) for ep in episodes)}"
  ]
  if os.path.isdir(path):  # zarr, RLDS, LeRobotDataset: the groups their metadata records
    for s in sets:
      n = [len(ep["actions"]) for ep in s.episodes]
      lines.append(f"  {export.group_name(s)}: {len(n)} episodes, mean length {np.mean(n):.1f}")
  else:  # HDF5: its filter keys
    with h5py.File(path, "r") as f:
      masks = {k: len(f[f"mask/{k}"]) for k in f["mask"]} if "mask" in f else {}
    lines += [f"  filter key {k}: {n} episodes" for k, n in masks.items()] or ["  no filter keys"]
  lines.append("  keys (of the first episode; time first):")
  lines += [f"    {k}: {v.shape} {v.dtype}" for k, v in _leaves(episodes[0])]
  lines.append(f"  provenance: {json.dumps(meta, sort_keys=True)}")
  return "\n".join(lines) + "\n"

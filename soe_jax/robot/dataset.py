"""A robot's dataset as a policy reads it: the spec from a LeRobotDataset's features and the robot config,
and the episodes checked against it.

The spec's observations are the dataset's `observation.*` features (or the config's `dataset.observations`),
low-dimensional vectors as they are, cameras resized to `dataset.image_size` when read; its actions the
`action` feature laid out as `dataset.actions` says, in the world frame, at the dataset's `fps`; each
part normalised by its range or left as it is, as `dataset.normalize` says per part (a part it does not
name: by range). With `dataset.rotation.to_6d`, each arm's axis-angle, quaternion or Euler part is
read as rotation-6d in the convention `dataset.rotation` states (`data.rotations`); the spec keeps
the robot's convention (`robot_rotations`), so the server replies in it and the recordings hold it.
The spec's `source` describes the dataset (`lerobot.description`: its robot type, tasks and
features), which a recording of the served policy takes its names from.
"""

from __future__ import annotations

from collections.abc import Sequence

import ml_collections
import numpy as np

from soe_jax.data import lerobot, rotations
from soe_jax.data.spec import PolicySpec
from soe_jax.runtime.errors import UserError

IMAGE_DTYPES = ("video", "image")
NORMS = ("range", "identity")  # a part's normaliser: its range mapped to [-1, 1], or none


def _plain(x):
  """ConfigDict / tuples -> plain dicts and lists (for the spec's JSON)."""
  if isinstance(x, ml_collections.ConfigDict):
    x = x.to_dict()
  if isinstance(x, dict):
    return {k: _plain(v) for k, v in x.items()}
  if isinstance(x, (list, tuple)):
    return [_plain(v) for v in x]
  return x


def action_norm(dataset: ml_collections.ConfigDict, arms: list) -> list[dict]:
  """Per arm, {part: "range" | "identity"} for every part of its action, from `dataset.normalize` (a part
  it does not name: range). A config saved before parts had their own field names the gripper's alone."""
  if "normalize" not in dataset:
    return [{"gripper": dataset.gripper} for _ in arms]
  if "gripper" in dataset:
    raise UserError("dataset.gripper is now dataset.normalize.gripper (one field per action part); drop the first")
  rules = _plain(dataset.normalize)
  bad = [f"dataset.normalize.{part} = {how!r}" for part, how in rules.items() if how not in NORMS]
  if bad:
    raise UserError(f"{', '.join(bad)}; known: {', '.join(NORMS)}")
  return [{part: rules.get(part, "range") for part, _ in arm} for arm in arms]


def robot_rotations(dataset: ml_collections.ConfigDict, arms: list) -> list | None:
  """Per arm the convention of the rotation part the policy gets as rotation-6d (`dataset.rotation`),
  or None where nothing converts (a config saved before the section existed converts nothing)."""
  if "rotation" not in dataset or not dataset.rotation.to_6d:
    return None
  r = dataset.rotation
  try:
    out = rotations.arm_conventions(arms, r.quaternion, r.euler, r.degrees)
  except ValueError as e:
    raise UserError(f"dataset.rotation: {e}") from None
  if not any(out):
    raise UserError(f"dataset.rotation.to_6d: no arm of dataset.actions has a part {', '.join(rotations.PARTS)} to "
                    f"convert: {arms}")  # fmt: skip
  return out


def spec_from_info(info: dict, dataset: ml_collections.ConfigDict, root: str = "the dataset",
                   tasks: Sequence[str] = ()) -> PolicySpec:  # fmt: skip
  """The spec of a policy for the dataset whose `meta/info.json` is `info` (and tasks `tasks`), under the
  robot config's `dataset` section (UserError naming what does not fit)."""
  features = info.get("features", {})
  keys = list(dataset.observations) or [k for k in features if k.startswith("observation.")]
  missing = [k for k in keys + ["action"] if k not in features]
  if missing:
    raise UserError(f"{root}: no feature {', '.join(missing)}; its features: {', '.join(features)}")
  size = tuple(int(n) for n in dataset.image_size)
  observations = {}
  for key in keys:
    f = features[key]
    shape = [int(n) for n in f["shape"]]
    if f["dtype"] in IMAGE_DTYPES:
      h, w = (size if size != (0, 0) else shape[:2]) if len(shape) == 3 else (0, 0)
      if len(shape) != 3 or shape[2] != 3:
        raise UserError(f"{root}: camera {key!r} has shape {shape}; height x width x 3 expected")
      observations[key] = dict(shape=[h, w, 3], dtype="uint8", image=True)
    else:
      observations[key] = dict(shape=shape, dtype="float32")
  arms = _plain(dataset.actions)
  size_a = sum(n for arm in arms for _, n in arm)
  (a_dim,) = features["action"]["shape"]
  if size_a != a_dim:
    raise UserError(f"{root}: the action feature has {a_dim} numbers, dataset.actions lays out {size_a}: {arms}")
  convs = robot_rotations(dataset, arms)
  policy_arms = rotations.policy_arms(arms, convs) if convs else arms
  try:
    return PolicySpec(
      observations=observations,
      actions=policy_arms,
      action_frame="world",
      control_hz=float(info["fps"]),
      action_box=_plain(dataset.action_box) or None,
      poses=_plain(dataset.poses) or None,
      action_norm=action_norm(dataset, policy_arms),
      robot_rotations=convs,
      source=lerobot.description(info, tasks),
    )
  except ValueError as e:
    raise UserError(f"{root}: {e}") from None


def spec_of(root: str, dataset: ml_collections.ConfigDict) -> PolicySpec:
  """The spec of the LeRobotDataset at `root` from its info and tasks (nothing of its episodes read)."""
  try:
    return spec_from_info(lerobot.read_info(root), dataset, root, lerobot.read_tasks(root))
  except lerobot.DatasetError as e:
    raise UserError(str(e)) from None


def read(root: str, dataset: ml_collections.ConfigDict, episodes=None, progress: bool = False):
  """(spec, episodes) of the LeRobotDataset at `root`: every episode's observations the spec reads
  (images resized to its size), actions (in the policy's layout: `dataset.rotation`), timestamps,
  success label and other columns (`lerobot.read_dataset`). UserError for a dataset that cannot be
  read or does not fit."""
  spec = spec_of(root, dataset)
  try:
    size = spec.image_shape
    _, found = lerobot.read_dataset(root, list(spec.observations), tuple(size) if size else None, episodes, progress)
  except lerobot.DatasetError as e:
    raise UserError(str(e)) from None
  for ep in found:
    ep["actions"] = spec.from_robot(ep["actions"])
    for key, v in spec.observations.items():
      got = tuple(np.asarray(ep["obs"][key]).shape[1:])
      if got != tuple(v["shape"]):
        raise UserError(
          f"{root}: episode {ep['episode_index']}: {key} has frames of shape {list(got)}, the spec {v['shape']}"
        )
  return spec, found

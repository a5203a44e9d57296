"""What a policy reads and writes, independent of where the data came from: the observation keys with
their shapes and dtypes (which are camera images, height x width x 3 uint8), the action layout per arm,
the frame the actions are in and the control rate. A checkpoint stores it as `spec.json` beside its
state, so a policy loads without the simulator's task registry; a task fills it
(`envs.registry.task_spec`), and so can a dataset of a robot's own.

  {"observations": {"robot0_eef_pos": {"shape": [3], "dtype": "float32"}, ...,
                    "agentview_image": {"shape": [84, 84, 3], "dtype": "uint8", "image": true}},
   "actions": [[["position", 3], ["rotation_6d", 6], ["gripper", 1]]],   one list per arm, in order
   "action_frame": "world", "control_hz": 20.0,
   "action_box": [{"position": [[x, y, z], [x, y, z]]}],   per arm, a part's lowest and highest values
   "poses": [{"position": "robot0_eef_pos", "orientation": "robot0_eef_quat", "quat_order": "xyzw"}],
   "action_norm": [{"gripper": "range"}],   per arm, how a part is normalised (default: position range)
   "robot_rotations": [{"part": "axis_angle", "convention": "rotvec", "degrees": false}],
   "source": {"robot_type": "so101", "tasks": ["pick the cube"],
              "features": {"observation.state": {"dtype": "float32", "shape": [6], "names": [...]}, ...}}}

The low-dimensional observation keys are concatenated in the order given (images are not); the action
is the arms' blocks one after another. `action_box` (optional) bounds the parts it names: the policy's
action normaliser maps the box to [-1, 1] (`policy.action_range = workspace`), so the policy can
command anything inside it and nothing outside. `poses` (optional) names each arm's end-effector pose
among the observations, which relative actions are expressed in (`policies.frames`). `action_norm`
(optional) says per arm which parts the normaliser maps to [-1, 1] ("range") and which it leaves as
they are ("identity"): positions by range, rotation-6d and the simulator's gripper (already in
[-1, 1]) as they are, by default; a real gripper in metres or counts by range. `robot_rotations`
(optional, `data.rotations`) says per arm which rotation part of the robot's own action, in which
convention, the policy's rotation-6d was converted from (None: none): the robot's recordings hold that
part, and the server's replies convert back to it (`to_robot`).

`source` (optional) describes the LeRobotDataset the policy was fitted on, as its `meta/info.json` and
`meta/tasks.parquet` say: its `robot_type`, its tasks and its `observation.*` and `action` features
(dtype, shape, names), cameras the policy does not read included. A recording of the served policy
takes its robot type, task, feature names and other cameras from it (`serve/recorder.py`). It is saved
with the spec but is no part of what the policy reads and writes: `to_dict` (the interface, which the
server's metadata sends and a re-fit compares a recording's spec by) leaves it out, and two specs
compare equal whatever their sources.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os

import numpy as np

from soe_jax.data import rotations

SPEC_FILE = "spec.json"
ACTION_FRAMES = ("world", "delta")  # absolute poses in the world frame | robomimic's scaled increments


@dataclasses.dataclass(frozen=True)
class PolicySpec:
  observations: dict  # key -> {"shape": [...], "dtype": str, "image": bool (absent: False)}
  actions: list  # per arm: [[part, size], ...]
  action_frame: str
  control_hz: float
  action_box: list | None = None  # per arm: {part: [lo (size,), hi (size,)]}
  poses: list | None = None  # per arm: {"position": key, "orientation": key, "quat_order": "xyzw" | "wxyz"}
  action_norm: list | None = None  # per arm: {part: "range" | "identity"} (default: position range)
  robot_rotations: list | None = None  # per arm: a robot's rotation convention (`data.rotations`) or None
  source: dict | None = dataclasses.field(default=None, compare=False)  # the fitted dataset's description

  def __post_init__(self):
    if self.action_frame not in ACTION_FRAMES:
      raise ValueError(f"unknown action frame {self.action_frame!r}; known: {', '.join(ACTION_FRAMES)}")
    sizes = {tuple(v.get("shape", ())) for k, v in self.observations.items() if v.get("image")}
    if len(sizes) > 1:
      raise ValueError(f"camera images of different shapes {sorted(sizes)}: one image size per policy")
    if self.action_box is not None:
      if len(self.action_box) != len(self.actions):
        raise ValueError(f"action_box has {len(self.action_box)} arms, the actions {len(self.actions)}")
      for k, (arm, box) in enumerate(zip(self.actions, self.action_box)):
        sizes = dict((part, size) for part, size in arm)
        for part, (lo, hi) in box.items():
          if part not in sizes:
            raise ValueError(f"action_box: arm {k} has no part {part!r}; its parts: {', '.join(sizes)}")
          if not (len(lo) == len(hi) == sizes[part]) or not all(a < b for a, b in zip(lo, hi)):
            raise ValueError(f"action_box: arm {k}'s {part} needs {sizes[part]} lows below their highs, got {lo}, {hi}")
    if self.robot_rotations is not None:
      if len(self.robot_rotations) != len(self.actions):
        raise ValueError(f"robot_rotations has {len(self.robot_rotations)} arms, the actions {len(self.actions)}")
      for k, (arm, c) in enumerate(zip(self.actions, self.robot_rotations)):
        if c and ["rotation_6d", 6] not in [list(p) for p in arm]:
          raise ValueError(f"robot_rotations: arm {k} converts {c['part']} to rotation_6d, which its action lacks")
        if c and c != rotations.convention(c["part"], c["convention"], c["convention"], c.get("degrees", False)):
          raise ValueError(f"robot_rotations: arm {k}'s {c} is not a convention (data.rotations)")

  @property
  def lowdim_keys(self) -> tuple[str, ...]:
    return tuple(k for k, v in self.observations.items() if not v.get("image"))

  @property
  def image_keys(self) -> tuple[str, ...]:
    return tuple(k for k, v in self.observations.items() if v.get("image"))

  @property
  def obs_dim(self) -> int:
    """The low-dimensional observation's size: the keys' sizes summed."""
    return sum(math.prod(self.observations[k]["shape"]) for k in self.lowdim_keys)

  @property
  def action_dim(self) -> int:
    return sum(size for arm in self.actions for _, size in arm)

  @property
  def image_shape(self) -> tuple[int, int] | None:
    """(height, width) of the camera images, or None without images."""
    keys = self.image_keys
    return tuple(self.observations[keys[0]]["shape"][:2]) if keys else None

  def action_bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
    """(lo, hi), each (action_dim,): `action_box` laid over the action, -inf / +inf in the parts it
    does not bound; None without a box."""
    if self.action_box is None:
      return None
    lo, hi = [], []
    for arm, box in zip(self.actions, self.action_box):
      for part, size in arm:
        lo += box[part][0] if part in box else [-np.inf] * size
        hi += box[part][1] if part in box else [np.inf] * size
    return np.asarray(lo, np.float64), np.asarray(hi, np.float64)

  def ranged_action_dims(self) -> np.ndarray:
    """(action_dim,) bool: the dims the normaliser maps to [-1, 1] (`action_norm`; positions by default)."""
    out = []
    for k, arm in enumerate(self.actions):
      rule = (self.action_norm or [{}] * len(self.actions))[k]
      for part, size in arm:
        how = rule.get(part, "range" if part == "position" else "identity")
        if how not in ("range", "identity"):
          raise ValueError(f"action_norm: arm {k}'s {part} is normalised by {how!r}; known: range, identity")
        out += [how == "range"] * size
    return np.asarray(out, bool)

  @property
  def robot_actions(self) -> list:
    """The robot's action layout (its recordings' and the server's replies'): the policy's, with each
    converted arm's rotation-6d as the robot's own rotation part."""
    if self.robot_rotations is None:
      return self.actions
    return [[[c["part"], rotations.PARTS[c["part"]]] if c and part == "rotation_6d" else [part, size]
             for part, size in arm] for arm, c in zip(self.actions, self.robot_rotations)]  # fmt: skip

  def to_robot(self, actions) -> np.ndarray:
    """(..., action_dim) policy actions -> the robot's layout (float32; as they are without conversion)."""
    if self.robot_rotations is None:
      return np.asarray(actions, np.float32)
    return rotations.convert(actions, self.actions, self.robot_rotations, to_policy=False)

  def from_robot(self, actions) -> np.ndarray:
    """(..., robot's action size) actions as the robot records them -> the policy's layout (float32)."""
    if self.robot_rotations is None:
      return np.asarray(actions, np.float32)
    return rotations.convert(actions, self.robot_actions, self.robot_rotations, to_policy=True)

  def position_indices(self, robot: bool = False) -> list[list[int]]:
    """Per arm, the action's indices of its commanded position (empty for an arm without one), in the
    policy's action or (`robot`) the robot's (`robot_actions`)."""
    out, start = [], 0
    for arm in self.robot_actions if robot else self.actions:
      idx = []
      for part, size in arm:
        if part == "position":
          idx = list(range(start, start + size))
        start += size
      out.append(idx)
    return out

  def to_dict(self) -> dict:
    """The interface: every field but `source`."""
    d = dataclasses.asdict(self)
    del d["source"]
    if d["robot_rotations"] is None:  # (a spec saved before the field existed reads the same)
      del d["robot_rotations"]
    return d

  @classmethod
  def from_dict(cls, d: dict, source: str = "spec") -> PolicySpec:
    missing = [k for k in ("observations", "actions", "action_frame", "control_hz") if k not in d]
    if missing:
      raise ValueError(f"{source}: missing {', '.join(missing)}")
    return cls(
      observations={k: dict(v) for k, v in d["observations"].items()},
      actions=[[list(p) for p in arm] for arm in d["actions"]],
      action_frame=d["action_frame"],
      control_hz=float(d["control_hz"]),
      action_box=d.get("action_box"),
      poses=d.get("poses"),
      action_norm=d.get("action_norm"),
      robot_rotations=d.get("robot_rotations"),
      source=d.get("source"),
    )


def save(directory: str, spec: PolicySpec) -> None:
  """`spec` as `directory`/spec.json: its interface and its source."""
  d = spec.to_dict() if spec.source is None else dict(spec.to_dict(), source=spec.source)
  with open(os.path.join(directory, SPEC_FILE), "w") as f:
    json.dump(d, f, indent=2)


def load(directory: str) -> PolicySpec | None:
  """The spec saved in `directory`, or None where there is none."""
  path = os.path.join(directory, SPEC_FILE)
  if not os.path.exists(path):
    return None
  with open(path) as f:
    return PolicySpec.from_dict(json.load(f), path)

"""The frame the policy's poses are in, converted at the policy's edge (the robot always sends and
receives absolute poses): `policy.action_frame`.

- `absolute`: as recorded (no conversion).
- `chunk_relative` (UMI's relative pose representation, `diffusion_policy/common/pose_repr_util.py`):
  every pose of the predicted chunk and every end-effector pose of the observation history expressed
  in the frame of the end-effector pose at the latest observation, `inv(base) @ pose`, per arm; the
  gripper and every other observation stay as they are. Sampled chunks go back by `base @ pose`.

Which observation keys are each arm's end-effector pose comes from the spec (`PolicySpec.poses`); the
action's layout is position (3), rotation-6d (6, the first two rows of the rotation matrix), gripper,
per arm. Everything here is pure JAX on raw units and broadcasts over the batch.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from soe_jax import geometry

FRAMES = ("absolute", "chunk_relative")


@dataclasses.dataclass(frozen=True)
class PoseLayout:
  """Where the poses are: per arm, the offsets in the low-dim observation vector of its end-effector
  position (3) and orientation quaternion (4, `quat_order` "xyzw" or "wxyz"), and in the action of its
  position (3) and rotation-6d (6). The spec names a pose part by its key or by [key, offset into it]
  (a robot's `observation.state` holding both)."""

  obs_position: tuple[int, ...]
  obs_quat: tuple[int, ...]
  quat_order: tuple[str, ...]
  action_position: tuple[int, ...]
  action_rot6d: tuple[int, ...]

  @classmethod
  def from_spec(cls, spec) -> PoseLayout:
    """From a `PolicySpec` with `poses` (ValueError naming what is missing otherwise)."""
    if not spec.poses:
      raise ValueError("policy.action_frame=chunk_relative needs the spec's `poses`: each arm's end-effector "
                       "position and orientation keys")  # fmt: skip
    if len(spec.poses) != len(spec.actions):
      raise ValueError(f"the spec has poses of {len(spec.poses)} arms and actions of {len(spec.actions)}")
    offsets, at = {}, 0
    for key in spec.lowdim_keys:
      offsets[key] = at
      at += int(np.prod(spec.observations[key]["shape"]))
    fields = {f: [] for f in ("obs_position", "obs_quat", "quat_order", "action_position", "action_rot6d")}

    def where(k, name, ref, size):
      """A pose part's offset: a key (its first `size` numbers) or [key, offset into it]."""
      key, at = (ref, 0) if isinstance(ref, str) else tuple(ref) if isinstance(ref, (list, tuple)) else (None, 0)
      if key not in offsets:
        raise ValueError(
          f"the spec's pose of arm {k}: {name} {ref!r} is not a low-dim observation key (or [key, offset])"
        )
      if not 0 <= at <= sizes[key] - size:
        raise ValueError(
          f"the spec's pose of arm {k}: {name} {ref!r} needs {size} numbers at {at} of {key!r} ({sizes[key]})"
        )
      return offsets[key] + at

    sizes = {k: int(np.prod(spec.observations[k]["shape"])) for k in spec.lowdim_keys}
    base = 0
    for k, (arm, pose) in enumerate(zip(spec.actions, spec.poses)):
      position, orientation = (
        where(k, "position", pose.get("position"), 3),
        where(k, "orientation", pose.get("orientation"), 4),
      )
      order = pose.get("quat_order", "xyzw")
      if order not in ("xyzw", "wxyz"):
        raise ValueError(f"the spec's pose of arm {k}: quat_order {order!r} is not xyzw or wxyz")
      parts, at = {}, base
      for part, size in arm:
        parts[part] = at
        at += size
      if "position" not in parts or "rotation_6d" not in parts:
        raise ValueError(
          f"chunk_relative needs each arm's action to hold position and rotation_6d, arm {k} has {list(parts)}"
        )
      fields["obs_position"].append(position)
      fields["obs_quat"].append(orientation)
      fields["quat_order"].append(order)
      fields["action_position"].append(parts["position"])
      fields["action_rot6d"].append(parts["rotation_6d"])
      base = at
    return cls(**{k: tuple(v) for k, v in fields.items()})

  def _base(self, obs_history, k: int):
    """Arm k's end-effector pose at the latest observation: (B, 3), (B, 3, 3)."""
    latest = obs_history[:, -1]
    pos = latest[:, self.obs_position[k] : self.obs_position[k] + 3]
    quat = latest[:, self.obs_quat[k] : self.obs_quat[k] + 4]
    return pos, geometry.quat_to_mat(quat, self.quat_order[k])

  def observe(self, obs_history):
    """Raw low-dim histories (B, To, D) -> the same with each arm's end-effector poses in the frame of
    its latest one (the latest becomes the origin and the identity)."""
    obs_history = out = jnp.asarray(obs_history)
    for k in range(len(self.obs_position)):
      pos, rot = self._base(obs_history, k)
      p, q = self.obs_position[k], self.obs_quat[k]
      rel_pos = jnp.einsum("bji,btj->bti", rot, obs_history[..., p : p + 3] - pos[:, None])
      rel_rot = jnp.einsum("bji,btjk->btik", rot, geometry.quat_to_mat(obs_history[..., q : q + 4], self.quat_order[k]))
      out = (
        out.at[..., p : p + 3].set(rel_pos).at[..., q : q + 4].set(geometry.mat_to_quat(rel_rot, self.quat_order[k]))
      )
    return out

  def to_relative(self, obs_history, actions):
    """Absolute actions (B, T, A) -> in the frame of each arm's latest end-effector pose of
    `obs_history` (B, To, D)."""
    obs_history, actions = jnp.asarray(obs_history), jnp.asarray(actions)
    out = actions
    for k in range(len(self.obs_position)):
      pos, rot = self._base(obs_history, k)
      a, r = self.action_position[k], self.action_rot6d[k]
      rel_pos = jnp.einsum("bji,btj->bti", rot, actions[..., a : a + 3] - pos[:, None])
      rel_rot = jnp.einsum("bji,btjk->btik", rot, geometry.rot6d_to_mat(actions[..., r : r + 6]))
      out = out.at[..., a : a + 3].set(rel_pos).at[..., r : r + 6].set(geometry.mat_to_rot6d(rel_rot))
    return out

  def to_absolute(self, obs_history, actions):
    """Relative actions (B, T, A) -> absolute (the inverse of `to_relative` for the same history)."""
    obs_history, actions = jnp.asarray(obs_history), jnp.asarray(actions)
    out = actions
    for k in range(len(self.obs_position)):
      pos, rot = self._base(obs_history, k)
      a, r = self.action_position[k], self.action_rot6d[k]
      abs_pos = pos[:, None] + jnp.einsum("bij,btj->bti", rot, actions[..., a : a + 3])
      abs_rot = jnp.einsum("bij,btjk->btik", rot, geometry.rot6d_to_mat(actions[..., r : r + 6]))
      out = out.at[..., a : a + 3].set(abs_pos).at[..., r : r + 6].set(geometry.mat_to_rot6d(abs_rot))
    return out

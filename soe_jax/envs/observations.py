"""The policy's view of a task's observations, pure JAX and free of MuJoCo and brax (the data, the
rollout engine, the strategies and the demonstrators read observations through it, and so does a
pure-JAX task's run).

Observations (`state.obs`) are a dict with robomimic's key names, per robot k:
  robot<k>_eef_pos (3)       grip-site position, world frame
  robot<k>_eef_quat (4)      hand orientation, xyzw
  robot<k>_gripper_qpos (2)  finger slide positions
then the task's `object` vector, and extras for experts and metrics (`robot<k>_eef_rot`, the grip
site's rotation matrix, row-major (9); `robot<k>_joint_pos`). The policy sees `policy_obs_keys(num_robots)`
concatenated in that order (`POLICY_OBS_KEYS` for one robot); `envs.manipulation` says what the MuJoCo
tasks put there.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from soe_jax import geometry

# Sizes of one robot's policy-observation keys, `robot<k>_` + each; `object` is the task's own
# (`ManipulationEnv.object_dim`).
ROBOT_KEY_SIZES = {"eef_pos": 3, "eef_quat": 4, "gripper_qpos": 2}
OBS_MODES = ("low_dim", "image")  # `env.obs_mode`: image adds the cameras' images to the observations


def policy_obs_sizes(object_dim: int, num_robots: int = 1) -> dict[str, int]:
  """{key: size} of the policy's observation, in its order: each robot's keys, then `object`."""
  sizes = {f"robot{k}_{key}": size for k in range(num_robots) for key, size in ROBOT_KEY_SIZES.items()}
  return {**sizes, "object": object_dim}


def policy_obs_keys(num_robots: int = 1) -> tuple[str, ...]:
  """The policy's observation keys in order, for `num_robots` robots."""
  return tuple(policy_obs_sizes(0, num_robots))


POLICY_OBS_KEYS = policy_obs_keys(1)
# What each policy-observation number is: (kind, size) in order; tasks give their `object_layout`.
ROBOT_OBS_LAYOUT = (("pos", 3), ("hand_quat", 4), ("finger", 2))
# The smallest span the normaliser maps to [-1, 1] per kind, from the quantity's physical range, so no
# dimension's gain exceeds 2 / span: positions 0.08 m (a tenth of the 0.8 m table, the workspace;
# gain <= 25 per m), fingers their 0.04 m travel (<= 50 per m), unit-quaternion components a quarter
# of their [-1, 1] range (<= 4).
# 0 / 1 indicators (`flag`) their whole range.
MIN_SPAN = {"pos": 0.08, "finger": 0.04, "hand_quat": 0.5, "quat": 0.5, "rel_quat": 0.5, "flag": 1.0}


def policy_obs_size(object_dim: int, num_robots: int = 1) -> int:
  """The policy's observation size for a task with an `object` vector of `object_dim` numbers."""
  return sum(policy_obs_sizes(object_dim, num_robots).values())


def split_policy_obs(obs, num_robots: int = 1):
  """(..., D) policy observations -> {key: (..., size)} in `policy_obs_keys` order (`object` takes the rest)."""
  out, start = {}, 0
  for k, size in policy_obs_sizes(obs.shape[-1] - policy_obs_size(0, num_robots), num_robots).items():
    out[k] = obs[..., start : start + size]
    start += size
  return out


def num_robots_in(obs: dict) -> int:
  """How many robots' keys the observations hold (robot0_..., robot1_..., ...)."""
  k = 0
  while f"robot{k}_eef_pos" in obs:
    k += 1
  return k


def eef_positions(obs: dict) -> jax.Array:
  """(..., R, 3): every robot's grip-site position, robot0 first."""
  return jnp.stack([obs[f"robot{k}_eef_pos"] for k in range(num_robots_in(obs))], -2)


def action_positions(actions: jax.Array, num_robots: int = 1) -> jax.Array:
  """(..., A) actions -> (..., R, 3): each robot's commanded position (the first 3 numbers of its block)."""
  return actions.reshape(actions.shape[:-1] + (num_robots, -1))[..., :3]


def pose_action(obs: dict, offset=0.0, grip=-1.0) -> jax.Array:
  """An absolute action (10 per robot): every arm's grip site at its pose in `obs`, moved by `offset`
  (3,), its gripper commanded to `grip`."""
  grip = jnp.reshape(jnp.asarray(grip, jnp.float32), (1,))
  return jnp.concatenate(
    [
      jnp.concatenate(
        [obs[f"robot{k}_eef_pos"] + offset, geometry.mat_to_rot6d(obs[f"robot{k}_eef_rot"].reshape(3, 3)), grip]
      )
      for k in range(num_robots_in(obs))
    ]
  )


def policy_obs(obs: dict, xp=jnp) -> jax.Array:
  """The policy's observation vector: every robot's low-dim keys, then `object`, concatenated, (..., 19
  or 23; 59 for two robots); `xp=np` on the host."""
  keys = policy_obs_keys(num_robots_in(obs))
  return xp.concatenate([xp.asarray(obs[k], xp.float32) for k in keys], axis=-1)


def policy_input(obs: dict, image_keys: tuple[str, ...] = (), lowdim_keys: tuple[str, ...] = ()):
  """What a policy reads of the observations: the low-dim vector (`policy_obs`, or the keys
  `lowdim_keys` in order: a policy's, which may leave out the object vector), or for a policy of camera
  images (`image_keys`, e.g. `manipulation.IMAGE_KEYS`) {"lowdim": that vector, "images": {key: (..., H,
  W, 3) uint8}}, the form an image policy's observation histories, buffer windows and normaliser take."""
  if lowdim_keys:
    vector = jnp.concatenate([jnp.asarray(obs[k], jnp.float32) for k in lowdim_keys], axis=-1)
  else:
    vector = policy_obs(obs)
  if not image_keys:
    return vector
  missing = [k for k in image_keys if k not in obs]
  if missing:
    raise ValueError(
      f"the policy reads images {', '.join(missing)}, which these observations lack (obs_mode='image' draws them)"
    )
  return {"lowdim": vector, "images": {k: obs[k] for k in image_keys}}


def select_keys(vector, object_dim: int, num_robots: int, keys: tuple[str, ...]):
  """The parts of a per-dimension vector over the full policy observation (`policy_obs`'s layout, e.g.
  a task's span floors) that the keys `keys` take, in their order."""
  sizes = policy_obs_sizes(object_dim, num_robots)
  starts = dict(zip(sizes, np.cumsum([0] + list(sizes.values()))))
  return np.concatenate([np.asarray(vector)[starts[k] : starts[k] + sizes[k]] for k in keys])

"""Tasks by name. `make_env("square")` builds one; unknown names list the known ones.

The MuJoCo tasks are registered by where their classes live and imported when a task is first made or
its class first read (the lazy registry, `soe_jax.registry`): this module, and what only names a task,
imports neither MuJoCo nor brax."""

from __future__ import annotations

from typing import TYPE_CHECKING

import ml_collections

from soe_jax.envs import controller, observations
from soe_jax.registry import Registry

if TYPE_CHECKING:
  from soe_jax.envs.manipulation import ManipulationEnv

TASKS: Registry[ManipulationEnv] = Registry("task")
register_env = TASKS.register
env_names = TASKS.names


def num_robots(name: str) -> int:
  """How many arms task `name` has (2 for transport, 1 for the others)."""
  return len(TASKS.factory(name).bases)


def action_size(name: str, action_mode: str) -> int:
  """The action size of task `name` in `action_mode`: 10 (absolute) or 7 (delta) per robot."""
  return controller.action_size(action_mode) * num_robots(name)


def image_keys(name: str) -> tuple[str, ...]:
  """The camera images task `name` draws with obs_mode="image" (robomimic's keys)."""
  return tuple(f"{c}_image" for c in TASKS.factory(name).image_cameras)


def task_spec(name: str, action_mode: str, cameras: tuple[str, ...] = (), image_size: int = 84) -> dict:
  """What a policy for task `name` reads and writes, as `data.spec.PolicySpec`'s dict: the policy's
  low-dimensional keys in order, the camera images `cameras` (of those the task draws) as
  image_size-square uint8 images, each arm's action blocks, the action frame, the control rate and
  the action box: the task's workspace (absolute positions), or the controller's input range [-1, 1]
  (robomimic's increments); none for a task without a workspace; and each arm's end-effector pose keys."""
  sizes = observations.policy_obs_sizes(TASKS.factory(name).object_dim, num_robots(name))
  obs = {k: dict(shape=[n], dtype="float32") for k, n in sizes.items()}
  drawn = image_keys(name)
  for key in cameras:
    if key not in drawn:
      raise ValueError(f"unknown camera image {key!r}; the {name} task draws {', '.join(drawn)}")
    obs[key] = dict(shape=[image_size, image_size, 3], dtype="uint8", image=True)
  arm = [list(part) for part in controller.action_layout(action_mode)]
  workspace = TASKS.factory(name).workspace
  if action_mode != "absolute":
    box = [{"position": [[-1.0] * 3, [1.0] * 3]}] * num_robots(name)  # the controller clips its inputs there
  else:
    box = None if workspace is None else [{"position": [list(lo), list(hi)]} for lo, hi in workspace]
  return dict(
    observations=obs,
    actions=[arm] * num_robots(name),
    action_frame="world" if action_mode == "absolute" else "delta",
    control_hz=1.0 / controller.CONTROL_DT,
    action_box=box,
    poses=[
      {"position": f"robot{k}_eef_pos", "orientation": f"robot{k}_eef_quat", "quat_order": "xyzw"}
      for k in range(num_robots(name))
    ],
  )


def make_env(name: str, config: ml_collections.ConfigDict | None = None, **overrides) -> ManipulationEnv:
  """Build task `name`; `overrides` replace fields of its default config (e.g. backend="mjx")."""
  factory = TASKS.factory(name)
  config = ml_collections.ConfigDict(config if config is not None else factory.default_config())
  config.update(overrides)
  return factory(config)


def env_from_config(env_config: ml_collections.ConfigDict) -> ManipulationEnv:
  """The task a run's `config.env` names (task, backend, action_mode, episode_length, ...)."""
  return make_env(env_config.task, **{k: v for k, v in env_config.items() if k != "task"})


register_env("lift", "soe_jax.envs.lift:Lift")
register_env("can", "soe_jax.envs.can:Can")
register_env("square", "soe_jax.envs.square:Square")
register_env("transport", "soe_jax.envs.transport:Transport")

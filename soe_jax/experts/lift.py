"""Lift demonstrator: over the cube, down, close, lift."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from soe_jax.envs import lift as lift_task
from soe_jax.experts import script
from soe_jax.experts.script import target, uniform


def sample_params(key):
  k = jax.random.split(key, 7)
  return dict(
    speed=uniform(k[0], 0.009, 0.016),
    settle=jax.random.randint(k[1], (), 2, 8),
    height=uniform(k[2], 0.05, 0.10),
    offset=uniform(k[3], -0.004, 0.004, (2,)),
    grasp_dz=uniform(k[4], -0.004, 0.004),
    close=jax.random.randint(k[5], (), 5, 10),
    yaw=uniform(k[6], -0.12, 0.12),
  )


def _cube(obs):
  return obs["object"][:3], script.quat_yaw_xyzw(obs["object"][3:7])


def _grasp_yaw(obs, p, cmd_yaw):
  _, yaw = _cube(obs)
  return script.nearest_equivalent(yaw + p["yaw"], cmd_yaw, jnp.pi / 2)


def settle(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, -1.0, p["speed"], hold=p["settle"])


def above(obs, p, cmd_pos, cmd_yaw):
  cube, _ = _cube(obs)
  pos = cube + jnp.concatenate([p["offset"], p["height"][None]])
  return target(pos, _grasp_yaw(obs, p, cmd_yaw), -1.0, p["speed"], tol=0.015)


def descend(obs, p, cmd_pos, cmd_yaw):
  cube, _ = _cube(obs)
  pos = cube + jnp.concatenate([p["offset"], p["grasp_dz"][None]])
  return target(pos, cmd_yaw, -1.0, 0.6 * p["speed"], hold=1, tol=0.008)


def close(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, 1.0, p["speed"], hold=p["close"], tol=0.02)


def lift(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos + jnp.array([0.0, 0.0, 0.12]), cmd_yaw, 1.0, p["speed"], hold=40, tol=0.02)


def resume(obs):
  """Holding the cube: lift; over it: descend; otherwise: go over it."""
  cube, _ = _cube(obs)
  over = script.near_xy(obs["robot0_eef_pos"], cube, 0.012)
  return jnp.where(script.gripping(obs, cube, lift_task.CUBE_HALF), 4, jnp.where(over, 2, 1))


EXPERT = script.ScriptedExpert(plans=(settle, above, descend, close, lift), sample_params=sample_params, resume=resume)

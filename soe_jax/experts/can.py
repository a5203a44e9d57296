"""Can demonstrators: over the can, down around its top, close, lift over the bin walls, carry to the
target compartment, lower, release, retreat. `EXPERT` is the scripted one; `VARIED` draws human-like
styles per episode (`lift.VARIED`'s, here for the approach and the carry to the bin): paths straight or
arced to either side, the grasp at any yaw around the can, the descent's own speed, and an occasional
hover over the can or over the compartment."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from soe_jax.envs import can as can_task
from soe_jax.experts import lift as lift_expert
from soe_jax.experts import script
from soe_jax.experts.script import target, uniform

CARRY_Z = 1.0
# Release over the part of the target compartment nearest the robot (its far corner is at the
# edge of the arm's reach with a top-down grasp), clear of the dividers by the can's radius.
PLACE_XY = (0.155, 0.338)


def sample_params(key):
  k = jax.random.split(key, 8)
  return dict(
    speed=uniform(k[0], 0.011, 0.018),
    settle=jax.random.randint(k[1], (), 2, 8),
    height=uniform(k[2], 0.97, 1.02),
    offset=uniform(k[3], -0.004, 0.004, (2,)),
    grasp_dz=uniform(k[4], 0.012, 0.020),
    close=jax.random.randint(k[5], (), 5, 10),
    place=uniform(k[6], -0.01, 0.01, (2,)),
    yaw=uniform(k[7], -0.3, 0.3),
  )


def settle(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, -1.0, p["speed"], hold=p["settle"])


def above(obs, p, cmd_pos, cmd_yaw):
  can = obs["object"][:3]
  pos = jnp.concatenate([can[:2] + p["offset"], p["height"][None]])
  return target(pos, cmd_yaw + p["yaw"], -1.0, p["speed"], tol=0.015)


def descend(obs, p, cmd_pos, cmd_yaw):
  can = obs["object"][:3]
  pos = jnp.concatenate([can[:2] + p["offset"], (can[2] + p["grasp_dz"])[None]])
  return target(pos, cmd_yaw, -1.0, 0.6 * p["speed"], hold=1, tol=0.008)


def close(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, 1.0, p["speed"], hold=p["close"], tol=0.02)


def lift(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos.at[2].set(CARRY_Z), cmd_yaw, 1.0, p["speed"], tol=0.02)


def carry(obs, p, cmd_pos, cmd_yaw):
  xy = jnp.asarray(PLACE_XY) + p["place"]
  return target(jnp.concatenate([xy, jnp.array([CARRY_Z])]), cmd_yaw, 1.0, p["speed"], tol=0.02)


def lower(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos.at[2].set(0.95), cmd_yaw, 1.0, 0.7 * p["speed"], tol=0.015)


def release(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, -1.0, p["speed"], hold=4, tol=0.03)


def retreat(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos.at[2].set(CARRY_Z), cmd_yaw, -1.0, p["speed"], hold=40)


def resume(obs):
  """Holding the can: lower it over the place, carry it at carrying height, or lift it there; the can
  in its compartment: retreat; over the can: descend; otherwise: go over it."""
  can, eef = obs["object"][:3], obs["robot0_eef_pos"]
  holding = script.gripping(obs, can.at[2].add(0.016), can_task.CAN_RADIUS)
  over_place = script.near_xy(eef, jnp.asarray(PLACE_XY), 0.03)
  carried = jnp.where(over_place, 6, jnp.where(eef[2] > CARRY_Z - 0.03, 5, 4))
  free = jnp.where(can_task.over_target(can), 8, jnp.where(script.near_xy(eef, can, 0.012), 2, 1))
  return jnp.where(holding, carried, free)


def sample_varied_params(key):
  k = jax.random.split(key, 6)
  p = dict(sample_params(k[0]), **lift_expert.sample_styles(k[1]), **lift_expert.path_styles(k[2]))
  return dict(p, yaw=uniform(k[3], -jnp.pi / 2, jnp.pi / 2))


EXPERT = script.ScriptedExpert(
  plans=(settle, above, descend, close, lift, carry, lower, release, retreat),
  sample_params=sample_params,
  resume=resume,
)

VARIED = script.ScriptedExpert(
  plans=lift_expert.styled_pick_and_place(*EXPERT.plans),
  sample_params=sample_varied_params,
  resume=resume,
)

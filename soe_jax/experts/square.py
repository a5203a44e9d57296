"""Square demonstrators: over the nut's handle, down, close, lift above the pegs, turn the nut square to
the peg while carrying it over, lower it onto the peg, release, retreat. `EXPERT` is the scripted one
(it turns the nut the shortest way square); `VARIED` draws human-like styles per episode (`lift.VARIED`'s
for the approach and the carry to the peg): paths straight or arced to either side, the descent's own
speed, an occasional hover over the handle or over the peg, and the nut turned to either of the two
nearest square orientations."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from soe_jax.envs import rotations
from soe_jax.envs import square as square_task
from soe_jax.experts import lift as lift_expert
from soe_jax.experts import script
from soe_jax.experts.script import target, uniform

CARRY_Z = 1.0
PEG_TOP = 0.95


def sample_params(key):
  k = jax.random.split(key, 7)
  return dict(
    speed=uniform(k[0], 0.010, 0.016),
    settle=jax.random.randint(k[1], (), 6, 12),
    height=uniform(k[2], 0.05, 0.09),
    along=uniform(k[3], 0.004, 0.012),
    grasp_dz=uniform(k[4], 0.003, 0.008),
    close=jax.random.randint(k[5], (), 5, 10),
    yaw=uniform(k[6], -0.1, 0.1),
  )


def _nut(obs):
  pos = obs["object"][:3]
  yaw = script.quat_yaw_xyzw(obs["object"][3:7])
  return pos, yaw


def _handle(obs, p):
  pos, yaw = _nut(obs)
  axis = jnp.array([jnp.cos(yaw), jnp.sin(yaw), 0.0])
  return pos + (square_task.HANDLE_OFFSET + p["along"]) * axis, yaw


def settle(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, -1.0, p["speed"], hold=p["settle"])


def above(obs, p, cmd_pos, cmd_yaw):
  handle, yaw = _handle(obs, p)
  # Close across the handle: the closing axis along the nut's local y.
  grasp_yaw = script.nearest_equivalent(yaw + jnp.pi / 2 + p["yaw"], cmd_yaw, jnp.pi)
  return target(handle.at[2].add(p["height"]), grasp_yaw, -1.0, p["speed"], tol=0.015)


def descend(obs, p, cmd_pos, cmd_yaw):
  handle, _ = _handle(obs, p)
  return target(handle.at[2].add(p["grasp_dz"]), cmd_yaw, -1.0, 0.6 * p["speed"], hold=1, tol=0.008)


def close(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, 1.0, p["speed"], hold=p["close"], tol=0.02)


def lift(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos.at[2].set(CARRY_Z), cmd_yaw, 1.0, p["speed"], tol=0.02)


def _over_peg(obs, cmd_pos, cmd_yaw, rotate: bool, second: jax.Array = 0.0):
  """Site target that puts the held nut's center over the square peg, turning it square if asked: the
  shortest way, or with `second` (0 or 1) the second shortest."""
  nut, nut_yaw = _nut(obs)
  eef = obs["robot0_eef_pos"]
  # Square to the peg with the handle pointing left, back or right: with the handle pointing away
  # (+x) the grip site would be beyond the arm's reach over the peg.
  turns = script.nearest_equivalent(jnp.array([0.5, 1.0, -0.5]) * jnp.pi, nut_yaw, 2 * jnp.pi) - nut_yaw
  turn = jnp.where(rotate, turns[jnp.argsort(jnp.abs(turns))[jnp.asarray(second, jnp.int32)]], 0.0)
  offset = rotations.rotz(turn) @ (nut - eef)  # nut center relative to the site after the turn
  pos = jnp.concatenate([jnp.asarray(square_task.SQUARE_PEG) - offset[:2], cmd_pos[2:]])
  return pos, cmd_yaw + turn, offset[2]


def carry(obs, p, cmd_pos, cmd_yaw):
  # (the scripted demonstrator turns the nut the shortest way; a varied one's `second` may pick the next)
  pos, yaw, _ = _over_peg(obs, cmd_pos, cmd_yaw, rotate=True, second=p.get("second", 0.0))
  return target(pos, yaw, 1.0, 1.2 * p["speed"], hold=3, tol=0.01)


def align(obs, p, cmd_pos, cmd_yaw):
  pos, yaw, dz = _over_peg(obs, cmd_pos, cmd_yaw, rotate=False)
  return target(pos.at[2].set(PEG_TOP + 0.02 - dz), yaw, 1.0, 0.6 * p["speed"], hold=3, tol=0.006)


def insert(obs, p, cmd_pos, cmd_yaw):
  pos, yaw, dz = _over_peg(obs, cmd_pos, cmd_yaw, rotate=False)
  return target(pos.at[2].set(square_task.TABLE_TOP + 0.012 - dz), yaw, 1.0, 0.5 * p["speed"], hold=2, tol=0.01)


def release(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos, cmd_yaw, -1.0, p["speed"], hold=4, tol=0.03)


def retreat(obs, p, cmd_pos, cmd_yaw):
  return target(cmd_pos.at[2].set(CARRY_Z), cmd_yaw, -1.0, p["speed"], hold=40)


def resume(obs):
  """Holding the nut: over the peg, release it when it is down, insert it once aligned just above the
  peg's top, else align; away from the peg, carry it at carrying height or lift it there. Not holding it:
  the nut on the peg: retreat; over the handle: descend; otherwise: go over the handle."""
  eef = obs["robot0_eef_pos"]
  handle, _ = _handle(obs, {"along": jnp.array(0.008)})
  nut, _ = _nut(obs)
  peg = jnp.asarray(square_task.SQUARE_PEG)
  holding = script.gripping(obs, handle, square_task.HANDLE_HALF_WIDTH, z_tol=0.025)
  on_peg = script.near_xy(nut, peg, 0.03) & (nut[2] < square_task.TABLE_TOP + 0.05)
  aligned = script.near_xy(nut, peg, 0.004) & (nut[2] < PEG_TOP + 0.03)
  at_peg = jnp.where(on_peg, 8, jnp.where(aligned, 7, 6))
  carried = jnp.where(script.near_xy(nut, peg, 0.015), at_peg, jnp.where(eef[2] > CARRY_Z - 0.03, 5, 4))
  free = jnp.where(on_peg, 9, jnp.where(script.near_xy(eef, handle, 0.012), 2, 1))
  return jnp.where(holding, carried, free)


def sample_varied_params(key):
  k = jax.random.split(key, 4)
  second = jax.random.randint(k[3], (), 0, 2).astype(jnp.float32)  # which square orientation the nut turns to
  return dict(sample_params(k[0]), **lift_expert.sample_styles(k[1]), **lift_expert.path_styles(k[2]), second=second)


EXPERT = script.ScriptedExpert(
  plans=(settle, above, descend, close, lift, carry, align, insert, release, retreat),
  sample_params=sample_params,
  resume=resume,
)

VARIED = script.ScriptedExpert(
  plans=lift_expert.styled_pick_and_place(*EXPERT.plans),
  sample_params=sample_varied_params,
  resume=resume,
)

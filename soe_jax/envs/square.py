"""Square: put the square nut onto the square peg (robosuite `NutAssemblySquare`,
`shared/specs/robomimic_tasks.md` 6.3).

Table top at z = 0.82 with a square peg (0.032 wide, at (0.23, 0.10)) and a round peg (radius 0.02,
at (0.23, -0.10)). The nut (outer square 0.0875, hole 0.0455, handle along its local x) starts at
x in [-0.115, -0.110], y in [0.11, 0.225] with a random yaw, dropped from z = 0.89.
Success (square peg only): |x - 0.23| < 0.03, |y - 0.10| < 0.03, z < 0.87 for the nut's body origin,
and the grip site farther than atanh(0.4) / 10 m from it. `object` = SquareNut_pos, SquareNut_quat
(xyzw), SquareNut_to_robot0_eef_pos, SquareNut_to_robot0_eef_quat (the nut's pose in the eef frame).
The round nut, parked outside the scene in this variant, is left out; the round peg collides as a
16-sided convex prism (MJX has no cylinder-box collisions).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

from soe_jax.envs import manipulation, panda, rotations

TABLE_TOP = 0.82
SQUARE_PEG = (0.23, 0.10)
ROUND_PEG = (0.23, -0.10)
PEG_HALF_HEIGHT = 0.1
HANDLE_OFFSET = 0.054  # handle site along the nut's local x
HANDLE_HALF_WIDTH = 0.015875  # the handle bar's half-extent across the nut's local x
RELEASE_DISTANCE = math.atanh(0.4) / 10.0
OBJECT_QPOS = 9
# Every position the demonstrator commands from 1,000 start states
# (x [-0.1817, 0.2354], y [-0.0445, 0.2890], z [0.8302, 1.0441]), widened
# by 2 cm on each side (`experts.workspace`):
#   python -m soe_jax experts --task=square --workspace --num_episodes=1000 --seed=90001
WORKSPACE = (((-0.2018, -0.0646, 0.8102), (0.2554, 0.3091, 1.0641)),)


class Square(manipulation.ManipulationEnv):
  name = "square"
  bases = (((-0.56, 0.0, 0.912), 0.0),)
  object_dim = 14
  mjx_contacts = 64  # the nut's boxes on the peg and the table: up to 28 in the demonstrations
  mjx_constraints = 384
  object_layout = (("pos", 3), ("quat", 4), ("pos", 3), ("rel_quat", 4))
  workspace = WORKSPACE

  def _assets_mjcf(self) -> str:
    return manipulation.prism_mesh("round_peg_mesh", 0.02, PEG_HALF_HEIGHT)

  def _scene_mjcf(self) -> str:
    bars = [
      ((0.0105, 0.04375, 0.01), (0.03325, 0, 0)),
      ((0.0105, 0.04375, 0.01), (-0.03325, 0, 0)),
      ((0.03125, 0.0105, 0.01), (0, 0.03325, 0)),
      ((0.03125, 0.0105, 0.01), (0, -0.03325, 0)),
      ((0.02525, HANDLE_HALF_WIDTH, 0.01), (HANDLE_OFFSET, 0, 0)),
    ]
    nut = "\n".join(
      f'<geom type="box" size="{manipulation.np_fmt(s)}" pos="{manipulation.np_fmt(p)}" density="100" condim="4" '
      f'friction="0.95 0.3 0.1" solimp="0.998 0.998 0.001" {panda.OBJECT_COLLISION} rgba="0.6 0.5 0.2 1"/>'
      for s, p in bars
    )
    (sx, sy), (rx, ry) = SQUARE_PEG, ROUND_PEG
    return f"""
    <geom name="table" type="box" size="0.4 0.4 0.025" pos="0 0 {TABLE_TOP - 0.025}" {panda.FIXTURE_COLLISION}
          friction="1 0.005 0.0001" rgba="0.8 0.7 0.6 1"/>
    <geom name="peg_square" type="box" size="0.016 0.016 {PEG_HALF_HEIGHT}" pos="{sx} {sy} 0.85"
          friction="1 0.005 0.0001" {panda.FIXTURE_COLLISION} rgba="0.5 0.5 0.5 1"/>
    <geom name="peg_round" type="mesh" mesh="round_peg_mesh" pos="{rx} {ry} 0.85"
          friction="1 0.005 0.0001" {panda.FIXTURE_COLLISION} rgba="0.5 0.5 0.5 1"/>
    <body name="nut" pos="-0.11 0.15 0.83">
      <freejoint name="nut_joint"/>
      {nut}
      <site name="handle_site" pos="{HANDLE_OFFSET} 0 0" size="0.005" group="2"/>
    </body>"""

  def _sample_objects(self, key: jax.Array) -> jax.Array:
    key_xy, key_yaw = jax.random.split(key)
    xy = jax.random.uniform(key_xy, (2,), minval=jnp.array([-0.115, 0.11]), maxval=jnp.array([-0.110, 0.225]))
    yaw = jax.random.uniform(key_yaw, (), maxval=2 * jnp.pi)
    return manipulation.yaw_free_qpos(jnp.concatenate([xy, jnp.array([TABLE_TOP + 0.02 + 0.05])]), yaw)

  def _object_obs(self, qpos, arms):
    arm = arms[0]
    pos, quat = manipulation.free_body_pose(qpos, OBJECT_QPOS)
    rel_pos, rel_quat = manipulation.pose_in_eef(pos, quat, arm.eef_pos, arm.hand_rot, arm.hand_quat)
    return jnp.concatenate([pos, rotations.wxyz_to_xyzw(quat), rel_pos, rel_quat])

  def _success(self, qpos, eef_pos):
    pos = qpos[OBJECT_QPOS : OBJECT_QPOS + 3]
    on_peg = (
      (jnp.abs(pos[0] - SQUARE_PEG[0]) < 0.03) & (jnp.abs(pos[1] - SQUARE_PEG[1]) < 0.03) & (pos[2] < TABLE_TOP + 0.05)
    )
    released = jnp.linalg.norm(eef_pos - pos) > RELEASE_DISTANCE
    return on_peg & released

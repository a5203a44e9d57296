"""Lift: pick the cube up off the table (robosuite `Lift`, `shared/specs/robomimic_tasks.md` 6.1).

Table 0.8 x 0.8, top at z = 0.8; cube at (0, 0) +- 3 cm with a random yaw, dropped 1 cm.
Success: the cube's center above z = 0.84. `object` = cube_pos (3), cube_quat (4, xyzw),
gripper_to_cube_pos (3, eef - cube, world).

Deviation: robosuite re-draws each cube half-extent from U[0.020, 0.022] on every reset (it rebuilds
the model); here the cube is a fixed 0.021 m half-extent, so that a batch of environments shares one
model on both backends.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from soe_jax.envs import manipulation, panda, rotations

TABLE_TOP = 0.8
CUBE_HALF = 0.021
SUCCESS_HEIGHT = TABLE_TOP + 0.04
OBJECT_QPOS = 9  # the cube's free joint starts here
# Every position the demonstrator commands from 1,000 start states (x [-0.1373, 0.0333], y [-0.0445,
# 0.0447], z [0.8145, 1.0440]), widened by 2 cm on each side (`experts.workspace`):
#   python -m soe_jax experts --task=lift --workspace --num_episodes=1000 --seed=90001
WORKSPACE = (((-0.1573, -0.0646, 0.7945), (0.0533, 0.0648, 1.0641)),)


class Lift(manipulation.ManipulationEnv):
  name = "lift"
  bases = (((-0.56, 0.0, 0.912), 0.0),)
  object_dim = 10
  object_layout = (("pos", 3), ("quat", 4), ("pos", 3))
  workspace = WORKSPACE

  def _scene_mjcf(self) -> str:
    return f"""
    <geom name="table" type="box" size="0.4 0.4 0.025" pos="0 0 {TABLE_TOP - 0.025}" {panda.FIXTURE_COLLISION}
          friction="1 0.005 0.0001" rgba="0.8 0.7 0.6 1"/>
    <body name="cube" pos="0 0 {TABLE_TOP + CUBE_HALF}">
      <freejoint name="cube_joint"/>
      <geom name="cube" type="box" size="{CUBE_HALF} {CUBE_HALF} {CUBE_HALF}" density="1000"
            friction="1 0.005 0.0001" solref="0.02 1" solimp="0.9 0.95 0.001" {panda.OBJECT_COLLISION}
            rgba="0.8 0.1 0.1 1"/>
    </body>"""

  def _sample_objects(self, key: jax.Array) -> jax.Array:
    key_xy, key_yaw = jax.random.split(key)
    xy = jax.random.uniform(key_xy, (2,), minval=-0.03, maxval=0.03)
    yaw = jax.random.uniform(key_yaw, (), maxval=2 * jnp.pi)
    return manipulation.yaw_free_qpos(jnp.concatenate([xy, jnp.array([TABLE_TOP + 0.01 + CUBE_HALF])]), yaw)

  def _object_obs(self, qpos, arms):
    arm = arms[0]
    pos, quat = manipulation.free_body_pose(qpos, OBJECT_QPOS)
    return jnp.concatenate([pos, rotations.wxyz_to_xyzw(quat), arm.eef_pos - pos])

  def _success(self, qpos, eef_pos):
    return qpos[OBJECT_QPOS + 2] > SUCCESS_HEIGHT

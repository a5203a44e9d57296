"""Actions -> joint-space servo targets, once per control step (pure JAX).

The policy's action is an absolute grip-site pose, 10 numbers: position (3), rotation-6d (6), gripper
(1), as Diffusion Policy uses for robomimic. The `delta` mode takes robomimic's 7-d OSC convention:
position increments of 0.05 m and a world-frame rotation vector of 0.5 rad per unit input (inputs
clipped to [-1, 1]), relative to the current grip-site pose, plus the gripper.

Differential IK (damped least squares, a few Gauss-Newton iterations on the JAX forward kinematics)
turns the pose target into joint targets for MuJoCo's position servos, which track them through the
physics substeps. The per-step Cartesian move is clipped, so a far target is approached smoothly
instead of with a torque spike. The gripper number is a position command: -1 fully open, +1 closed.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from soe_jax import geometry
from soe_jax.envs import panda, rotations

# One arm's action, in order: an absolute pose (position, rotation-6d) or robomimic's increments
# (position, axis-angle), then the gripper.
ACTION_LAYOUTS = {
  "absolute": (("position", 3), ("rotation_6d", 6), ("gripper", 1)),
  "delta": (("position", 3), ("axis_angle", 3), ("gripper", 1)),
}
CONTROL_DT = 0.05  # s per control step (20 Hz)
MAX_STEP_POS = 0.03  # m per control step (0.6 m/s)
MAX_STEP_ROT = 0.3  # rad per control step
IK_DAMPING = 0.05
IK_ITERS = 3
NULLSPACE_GAIN = 0.05  # pulls the redundant degree of freedom towards the initial posture


def action_layout(mode: str) -> tuple[tuple[str, int], ...]:
  if mode not in ACTION_LAYOUTS:
    raise ValueError(f"unknown action mode {mode!r}; known: {', '.join(ACTION_LAYOUTS)}")
  return ACTION_LAYOUTS[mode]


def action_size(mode: str) -> int:
  return sum(n for _, n in action_layout(mode))


def _clip_norm(v: jax.Array, max_norm: float) -> jax.Array:
  n = jnp.linalg.norm(v)
  return v * jnp.minimum(1.0, max_norm / jnp.maximum(n, 1e-9))


def pose_target(mode: str, action: jax.Array, site_pos: jax.Array, site_rot: jax.Array):
  """-> (target position (3,), target rotation (3, 3), gripper command in [-1, 1])."""
  if mode == "absolute":
    return action[:3], geometry.rot6d_to_mat(action[3:9]), jnp.clip(action[9], -1.0, 1.0)
  a = jnp.clip(action, -1.0, 1.0)
  return site_pos + 0.05 * a[:3], rotations.axis_angle_to_mat(0.5 * a[3:6]) @ site_rot, a[6]


def ik_targets(kin: panda.Kinematics, q: jax.Array, target_pos: jax.Array, target_rot: jax.Array) -> jax.Array:
  """Joint targets (7,) moving the grip site from its pose at `q` towards the target by at most one step."""
  fk = kin.forward(q)
  goal_pos = fk["site_pos"] + _clip_norm(target_pos - fk["site_pos"], MAX_STEP_POS)
  rot_err = _clip_norm(rotations.rotation_error(fk["site_rot"], target_rot), MAX_STEP_ROT)
  goal_rot = rotations.axis_angle_to_mat(rot_err) @ fk["site_rot"]
  lo, hi = jnp.asarray(panda.JOINT_RANGE[:, 0]) + 1e-3, jnp.asarray(panda.JOINT_RANGE[:, 1]) - 1e-3
  posture = jnp.asarray(panda.INIT_QPOS)

  def iteration(qi, _):
    f = kin.forward(qi)
    err = jnp.concatenate([goal_pos - f["site_pos"], rotations.rotation_error(f["site_rot"], goal_rot)])
    jac = f["jac"]
    jjt = jac @ jac.T + IK_DAMPING**2 * jnp.eye(6)
    pinv = jac.T @ jnp.linalg.solve(jjt, jnp.eye(6))
    null = jnp.eye(7) - pinv @ jac
    dq = pinv @ err + null @ (NULLSPACE_GAIN * (posture - qi))
    return jnp.clip(qi + dq, lo, hi), None

  q_target, _ = jax.lax.scan(iteration, q, None, length=IK_ITERS)
  return q_target


def gripper_targets(command: jax.Array) -> jax.Array:
  """Gripper command in [-1, 1] -> finger slide targets (2,): -1 open (+-0.04 m), +1 closed (0)."""
  opening = panda.FINGER_TRAVEL * 0.5 * (1.0 - jnp.clip(command, -1.0, 1.0))
  return jnp.stack([opening, -opening])


def joint_controls(kin: panda.Kinematics, mode: str, action: jax.Array, q: jax.Array) -> jax.Array:
  """Action -> the (9,) control vector of the arm and finger servos."""
  fk = kin.forward(q)
  pos, rot, grip = pose_target(mode, action, fk["site_pos"], fk["site_rot"])
  return jnp.concatenate([ik_targets(kin, q, pos, rot), gripper_targets(grip)])

"""Forward kinematics against MuJoCo, rotation conventions, and tracking of pose targets."""

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from soe_jax import geometry
from soe_jax.envs import controller, panda, rotations


def test_forward_kinematics_matches_mujoco(jitted_env):
  env, _, _ = jitted_env("lift")
  m = env.mj_model
  d = mujoco.MjData(m)
  site = m.site("grip_site").id
  hand = m.body("right_hand").id
  rng = np.random.default_rng(0)
  for _ in range(5):
    q = (panda.INIT_QPOS + rng.normal(0, 0.3, 7)).astype(np.float32)
    d.qpos[:7] = q
    mujoco.mj_forward(m, d)
    fk = env.kin.forward(jnp.asarray(q))
    np.testing.assert_allclose(fk["site_pos"], d.site_xpos[site], atol=1e-5)
    np.testing.assert_allclose(np.asarray(fk["site_rot"]).ravel(), d.site_xmat[site], atol=1e-5)
    np.testing.assert_allclose(np.asarray(fk["hand_rot"]).ravel(), d.xmat[hand], atol=1e-5)
    jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    mujoco.mj_jacSite(m, d, jp, jr, site)
    np.testing.assert_allclose(fk["jac"], np.concatenate([jp, jr])[:, :7], atol=1e-5)


def test_initial_eef_pose_matches_robosuite():
  fk = panda.Kinematics((-0.56, 0.0, 0.912)).forward(jnp.asarray(panda.INIT_QPOS))
  np.testing.assert_allclose(fk["site_pos"], [-0.1028, 0.0, 1.0110], atol=2e-4)
  quat_xyzw = rotations.wxyz_to_xyzw(geometry.mat_to_quat_wxyz(fk["hand_rot"]))
  np.testing.assert_allclose(np.abs(quat_xyzw), [0.998, 0.0002, 0.0636, 0.0], atol=2e-3)


def test_rotation_conversions_round_trip():
  v = jax.random.normal(jax.random.PRNGKey(0), (64, 3))
  mats = rotations.axis_angle_to_mat(v)
  np.testing.assert_allclose(geometry.rot6d_to_mat(geometry.mat_to_rot6d(mats)), mats, atol=1e-5)
  np.testing.assert_allclose(geometry.quat_wxyz_to_mat(geometry.mat_to_quat_wxyz(mats)), mats, atol=1e-5)
  np.testing.assert_allclose(rotations.axis_angle_to_mat(jnp.zeros(3)), np.eye(3), atol=1e-7)


def test_controller_reaches_reachable_target_smoothly(jitted_env):
  env, reset, step = jitted_env("lift")
  state = reset(jax.random.PRNGKey(0))
  start = np.asarray(state.obs["robot0_eef_pos"])
  goal = start + np.array([0.06, -0.05, -0.08], np.float32)
  goal_rot = rotations.axis_angle_to_mat(jnp.array([0.0, 0.0, 0.4])) @ state.obs["robot0_eef_rot"].reshape(3, 3)
  action = jnp.concatenate([jnp.asarray(goal), geometry.mat_to_rot6d(goal_rot), jnp.array([-1.0])])
  errors = []
  for _ in range(40):
    state = step(state, action)
    errors.append(np.linalg.norm(np.asarray(state.obs["robot0_eef_pos"]) - goal))
  rot_err = np.linalg.norm(rotations.rotation_error(state.obs["robot0_eef_rot"].reshape(3, 3), goal_rot))
  assert errors[-1] < 0.003, errors[-1]
  assert rot_err < 0.02, rot_err
  # No oscillation: once within 1 cm the error never grows back by more than 1 mm.
  settled = errors[int(np.argmax(np.asarray(errors) < 0.01)) :]
  assert max(np.diff(settled), default=0.0) < 1e-3


def test_delta_mode_moves_by_its_scale():
  from soe_jax.envs.registry import make_env

  env = make_env("lift", action_mode="delta")
  state = jax.jit(env.reset)(jax.random.PRNGKey(0))
  step = jax.jit(env.step)
  start = np.asarray(state.obs["robot0_eef_pos"])
  for _ in range(10):  # +0.5 in x: 2.5 cm per step requested
    state = step(state, jnp.array([0.5, 0, 0, 0, 0, 0, -1.0]))
  moved = np.asarray(state.obs["robot0_eef_pos"]) - start
  # Each step aims 2.5 cm ahead of where the arm is; it covers most of that, never more.
  assert 0.10 < moved[0] < 0.25 and abs(moved[1]) < 0.01 and abs(moved[2]) < 0.01, moved


def test_gripper_command_is_a_position():
  np.testing.assert_allclose(controller.gripper_targets(jnp.array(-1.0)), [0.04, -0.04])
  np.testing.assert_allclose(controller.gripper_targets(jnp.array(1.0)), [0.0, 0.0])
  np.testing.assert_allclose(controller.gripper_targets(jnp.array(0.0)), [0.02, -0.02])

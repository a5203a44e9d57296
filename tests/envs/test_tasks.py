"""Start states, success checks, resting objects, and the interface errors of the three tasks."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from soe_jax.envs import can, env_names, lift, make_env, rotations, square
from soe_jax.envs.manipulation import policy_obs

TASKS = env_names()
OBS_SIZES = {"lift": 19, "can": 23, "square": 23}


def _hold_action(obs):
  return jnp.concatenate(
    [obs["robot0_eef_pos"], rotations.mat_to_rot6d(obs["robot0_eef_rot"].reshape(3, 3)), jnp.array([-1.0])]
  )


@pytest.mark.parametrize("task", TASKS)
def test_same_key_same_start_different_keys_differ(task, jitted_env):
  env, reset, _ = jitted_env(task)
  a = reset(jax.random.PRNGKey(3))
  b = reset(jax.random.PRNGKey(3))
  c = reset(jax.random.PRNGKey(4))
  np.testing.assert_array_equal(a.pipeline_state.raw, b.pipeline_state.raw)
  np.testing.assert_array_equal(a.pipeline_state.qpos, b.pipeline_state.qpos)
  assert not np.allclose(a.pipeline_state.qpos[9:12], c.pipeline_state.qpos[9:12])
  assert policy_obs(a.obs).shape == (OBS_SIZES[task],) == (env.observation_size,)


RANGES = {  # object x, y bounds and initial z from the spec
  "lift": ((-0.03, 0.03), (-0.03, 0.03), lift.TABLE_TOP + 0.01 + lift.CUBE_HALF),
  "can": ((-0.02, 0.22), (-0.42, -0.08), can.FLOOR_TOP + can.CAN_HALF_HEIGHT),
  "square": ((-0.115, -0.110), (0.11, 0.225), 0.89),
}


@pytest.mark.parametrize("task", TASKS)
def test_start_states_within_spec_ranges(task, jitted_env):
  env, _, _ = jitted_env(task)
  qpos = jax.vmap(env.sample_qpos)(jax.random.split(jax.random.PRNGKey(0), 256))
  (x0, x1), (y0, y1), z = RANGES[task]
  obj = np.asarray(qpos[:, 9:12])
  assert (obj[:, 0] >= x0).all() and (obj[:, 0] <= x1).all()
  assert (obj[:, 1] >= y0).all() and (obj[:, 1] <= y1).all()
  np.testing.assert_allclose(obj[:, 2], z, atol=1e-6)
  # Spread over the range, not a constant.
  assert obj[:, 0].std() > 0.2 * (x1 - x0) / np.sqrt(12) and obj[:, 1].std() > 0.2 * (y1 - y0) / np.sqrt(12)
  # Yaw only (upright), uniform over the circle.
  quat = np.asarray(qpos[:, 12:16])
  np.testing.assert_allclose(quat[:, 1:3], 0.0, atol=1e-6)
  yaw = 2 * np.arctan2(quat[:, 3], quat[:, 0])
  assert np.cos(yaw).std() > 0.5 and np.sin(yaw).std() > 0.5
  # Arm: the initial pose plus 0.02 rad noise.
  arm = np.asarray(qpos[:, :7])
  from soe_jax.envs import panda

  assert 0.01 < (arm - panda.INIT_QPOS).std() < 0.03


def _success(env, obj_pos, eef_pos):
  qpos = env.sample_qpos(jax.random.PRNGKey(0)).at[9:12].set(jnp.asarray(obj_pos, jnp.float32))
  return bool(env._success(qpos, jnp.asarray(eef_pos, jnp.float32)))


def test_lift_success_threshold():
  env = make_env("lift")
  far = [0.0, 0.0, 1.2]
  assert _success(env, [0.0, 0.0, lift.SUCCESS_HEIGHT + 0.002], far)
  assert not _success(env, [0.0, 0.0, lift.SUCCESS_HEIGHT - 0.002], far)


def test_can_success_right_bin_wrong_bin_and_release():
  env = make_env("can")
  inside = [can.TARGET_CENTER[0], can.TARGET_CENTER[1], 0.86]
  away = [0.0, 0.0, 1.2]
  assert _success(env, inside, away)
  assert not _success(env, [0.1975, 0.1525, 0.86], away)  # target bin, wrong compartment
  assert not _success(env, [0.1, -0.25, 0.86], away)  # source bin
  assert not _success(env, [0.2975 + 0.004, 0.4025, 0.86], away)  # just past the compartment's x bound
  assert not _success(env, [inside[0], inside[1], 0.905], away)  # above the rim
  # Gripper still at the can: not released.
  assert not _success(env, inside, [inside[0], inside[1], inside[2] + 0.03])
  assert _success(env, inside, [inside[0], inside[1], inside[2] + 0.05])


def test_square_success_square_peg_round_peg_beside():
  env = make_env("square")
  away = [0.0, 0.0, 1.2]
  on_square = [square.SQUARE_PEG[0], square.SQUARE_PEG[1], 0.83]
  assert _success(env, on_square, away)
  assert not _success(env, [square.ROUND_PEG[0], square.ROUND_PEG[1], 0.83], away)
  assert not _success(env, [square.SQUARE_PEG[0] + 0.035, square.SQUARE_PEG[1], 0.83], away)  # beside
  assert not _success(env, [square.SQUARE_PEG[0], square.SQUARE_PEG[1], 0.95], away)  # on top of the peg
  assert not _success(env, on_square, [on_square[0], on_square[1], on_square[2] + 0.02])  # still held


@pytest.mark.parametrize("task", TASKS)
def test_object_resting_on_table_stays_put(task, jitted_env):
  env, reset, step = jitted_env(task)
  state = reset(jax.random.PRNGKey(1))
  action = _hold_action(state.obs)
  for _ in range(20):  # let the object drop onto the table (1 s)
    state = step(state, action)
  before = np.asarray(state.obs["object"][:3])
  for _ in range(100):  # 5 simulated seconds
    state = step(state, action)
  drift = np.linalg.norm(np.asarray(state.obs["object"][:3]) - before)
  assert drift < 1e-3, drift


def test_unknown_task_lists_known_ones():
  with pytest.raises(ValueError, match="known tasks: can, lift, square"):
    make_env("sqaure")


def test_bad_action_shape_says_expected_shape(jitted_env):
  env, reset, _ = jitted_env("lift")
  state = reset(jax.random.PRNGKey(0))
  with pytest.raises(ValueError, match=r"expected an action of shape \(10,\).*got \(7,\)"):
    env.step(state, jnp.zeros(7))


def test_unknown_backend_lists_known_ones():
  with pytest.raises(ValueError, match="known physics backends: auto, mjx, mujoco"):
    make_env("lift", backend="gpu")

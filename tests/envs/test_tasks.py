"""Start states, success checks, resting objects, and the interface errors of the tasks."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from soe_jax import geometry
from soe_jax.envs import can, lift, panda, square, transport
from soe_jax.envs.observations import policy_obs, pose_action, split_policy_obs
from soe_jax.envs.registry import env_names, make_env

TASKS = env_names()
OBS_SIZES = {"lift": 19, "can": 23, "square": 23, "transport": 59}
ACTION_SIZES = {"lift": 10, "can": 10, "square": 10, "transport": 20}


def _hold_action(obs):
  """Every arm holds its pose, gripper open."""
  return pose_action(obs)


@pytest.mark.parametrize("task", TASKS)
def test_same_key_same_start_different_keys_differ(task, jitted_env):
  env, reset, _ = jitted_env(task)
  a = reset(jax.random.PRNGKey(3))
  b = reset(jax.random.PRNGKey(3))
  c = reset(jax.random.PRNGKey(4))
  np.testing.assert_array_equal(a.pipeline_state.raw, b.pipeline_state.raw)
  np.testing.assert_array_equal(a.pipeline_state.qpos, b.pipeline_state.qpos)
  objects = slice(panda.NUM_ROBOT_QPOS * env.num_robots, None)
  assert not np.allclose(a.pipeline_state.qpos[objects], c.pipeline_state.qpos[objects])
  assert policy_obs(a.obs).shape == (OBS_SIZES[task],) == (env.observation_size,)
  assert env.action_size == ACTION_SIZES[task]


RANGES = {  # object x, y bounds and initial z from the spec
  "lift": ((-0.03, 0.03), (-0.03, 0.03), lift.TABLE_TOP + 0.01 + lift.CUBE_HALF),
  "can": ((-0.02, 0.22), (-0.42, -0.08), can.FLOOR_TOP + can.CAN_HALF_HEIGHT),
  "square": ((-0.115, -0.110), (0.11, 0.225), 0.89),
}


@pytest.mark.parametrize("task", list(RANGES))
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
def test_objects_resting_stay_put(task, jitted_env):
  env, reset, step = jitted_env(task)
  state = reset(jax.random.PRNGKey(1))
  action = _hold_action(state.obs)
  for _ in range(20):  # let the objects drop onto what holds them (1 s)
    state = step(state, action)
  free = np.arange(panda.NUM_ROBOT_QPOS * env.num_robots, env.mj_model.nq).reshape(-1, 7)[:, :3]  # positions
  before = np.asarray(state.pipeline_state.qpos)[free]
  for _ in range(100):  # 5 simulated seconds
    state = step(state, action)
  drift = np.linalg.norm(np.asarray(state.pipeline_state.qpos)[free] - before, axis=-1)
  assert drift.max() < 1e-3, drift


def test_unknown_task_lists_known_ones():
  with pytest.raises(ValueError, match="known tasks: can, lift, square, transport"):
    make_env("sqaure")


def test_bad_action_shape_says_expected_shape(jitted_env):
  env, reset, _ = jitted_env("lift")
  state = reset(jax.random.PRNGKey(0))
  with pytest.raises(ValueError, match=r"expected an action of shape \(10,\).*got \(7,\)"):
    env.step(state, jnp.zeros(7))


def test_unknown_backend_lists_known_ones():
  with pytest.raises(ValueError, match="known physics backends: auto, mjx, mujoco"):
    make_env("lift", backend="gpu")


def test_transport_start_states_within_spec_ranges(jitted_env):
  env, _, _ = jitted_env("transport")
  qpos = np.asarray(jax.vmap(env.sample_qpos)(jax.random.split(jax.random.PRNGKey(0), 256)))
  for start, center, z in (
    (transport.LID_QPOS, transport.START_BIN, transport.WALL_TOP + transport.LID_PLATE[2] + transport.DROP),
    (transport.PAYLOAD_QPOS, transport.START_BIN, transport.PLATE_TOP + transport.HEAD + transport.DROP),
    (transport.TRASH_QPOS, transport.TARGET_BIN, transport.PLATE_TOP + transport.TRASH_HALF + transport.DROP),
  ):
    offset = qpos[:, start : start + 2] - np.asarray(center[:2])
    assert np.abs(offset).max() <= transport.JITTER + 1e-6 and offset.std() > 0.002
    np.testing.assert_allclose(qpos[:, start + 2], z, atol=1e-6)
  np.testing.assert_allclose(qpos[:, transport.LID_QPOS + 3 : transport.LID_QPOS + 7], [[1, 0, 0, 0]] * 256, atol=1e-6)
  # The hammer lies flat, its handle (body z) along world +y or -y, both ends drawn, within 30 degrees.
  quat = qpos[:, transport.PAYLOAD_QPOS + 3 : transport.PAYLOAD_QPOS + 7]
  handle = np.asarray(jax.vmap(geometry.quat_wxyz_to_mat)(quat))[:, :, 2]
  np.testing.assert_allclose(handle[:, 2], 0.0, atol=1e-5)
  assert (handle[:, 1] > 0).mean() > 0.3 and (handle[:, 1] < 0).mean() > 0.3
  assert np.abs(handle[:, 1]).min() >= np.cos(np.pi / 6) - 1e-5
  assert (quat[:, 0] > 0.6).all()  # far from the hemisphere boundary of the object-quaternion convention
  trash_yaw = 2 * np.arctan2(qpos[:, transport.TRASH_QPOS + 6], qpos[:, transport.TRASH_QPOS + 3])
  assert np.abs(trash_yaw).max() <= 0.3 * np.pi + 1e-5 and trash_yaw.std() > 0.3
  # Both arms: the initial pose plus 0.02 rad noise, drawn independently.
  arms = qpos[:, [*range(7), *range(9, 16)]].reshape(256, 2, 7) - panda.INIT_QPOS
  assert 0.01 < arms.std() < 0.03 and abs(np.corrcoef(arms[:, 0, 0], arms[:, 1, 0])[0, 1]) < 0.2


def _placed(env, payload=None, trash=None):
  """qpos of a start state with the hammer's and the trash cube's free joints replaced."""
  qpos = np.array(env.sample_qpos(jax.random.PRNGKey(0)))
  if payload is not None:
    qpos[transport.PAYLOAD_QPOS : transport.PAYLOAD_QPOS + 7] = payload
  if trash is not None:
    qpos[transport.TRASH_QPOS : transport.TRASH_QPOS + 7] = np.concatenate([trash, [1, 0, 0, 0]])
  return jnp.asarray(qpos)


def test_transport_success_needs_both_objects_on_their_plates(jitted_env):
  env, reset, step = jitted_env("transport")
  tx, ty, _ = transport.TARGET_BIN
  rest = transport.PLATE_TOP + transport.HEAD  # the hammer rests on its head
  hammer_in_target = transport.payload_pose((tx, ty - 0.02, rest), 0.3)
  trash_in_trash = (transport.TRASH_BIN[0] + 0.03, transport.TRASH_BIN[1], transport.PLATE_TOP + transport.TRASH_HALF)
  away = jnp.array([0.0, 0.0, 1.3])
  success = lambda qpos: bool(env._success(qpos, away))
  flags = lambda qpos: np.asarray(env._placed(qpos), float)
  assert success(_placed(env, hammer_in_target, trash_in_trash))
  np.testing.assert_array_equal(flags(_placed(env, hammer_in_target, trash_in_trash)), [1, 1])
  # The hammer in the target bin, the trash still there too (its start): not yet.
  assert not success(_placed(env, hammer_in_target))
  np.testing.assert_array_equal(flags(_placed(env, hammer_in_target)), [1, 0])
  # The trash in the trash bin, the hammer still in the start bin: not yet.
  assert not success(_placed(env, trash=trash_in_trash))
  np.testing.assert_array_equal(flags(_placed(env, trash=trash_in_trash)), [0, 1])
  # Just outside: the hammer 1 cm above the plate, or in the trash bin; the trash cube above its plate.
  lifted = transport.payload_pose((tx, ty - 0.02, rest + 0.01), 0.3)
  assert not success(_placed(env, lifted, trash_in_trash))
  wrong_bin = transport.payload_pose((transport.TRASH_BIN[0], transport.TRASH_BIN[1], rest), 0.0)
  assert not success(_placed(env, wrong_bin, (trash_in_trash[0], trash_in_trash[1] - 0.07, trash_in_trash[2])))
  assert not success(_placed(env, hammer_in_target, np.add(trash_in_trash, (0, 0, 0.01))))
  # Released there, the objects settle on the plates and the check holds (the physics agrees).
  state = reset(jax.random.PRNGKey(0))
  qpos = _placed(env, hammer_in_target + np.array([0, 0, 0.002, 0, 0, 0, 0]), np.add(trash_in_trash, (0, 0, 0.002)))
  state = state.replace(pipeline_state=env.physics.init(qpos, jnp.zeros(env.mj_model.nv, jnp.float32)))
  for _ in range(20):
    state = step(state, _hold_action(state.obs))
  assert float(state.metrics["success"]) == 1.0
  np.testing.assert_array_equal(state.obs["object"][-2:], [1, 1])  # payload_in_target_bin, trash_in_trash_bin


def test_two_robot_policy_obs_split_back_into_robomimics_keys(jitted_env):
  env, reset, _ = jitted_env("transport")
  obs = reset(jax.random.PRNGKey(0)).obs
  vector = np.asarray(policy_obs(obs))
  keys = ("robot0_eef_pos", "robot0_eef_quat", "robot0_gripper_qpos", "robot1_eef_pos", "robot1_eef_quat")
  assert env.policy_obs_keys == keys + ("robot1_gripper_qpos", "object")
  parts = split_policy_obs(vector, env.num_robots)
  assert list(parts) == list(env.policy_obs_keys)
  for k, v in parts.items():
    np.testing.assert_array_equal(v, obs[k])

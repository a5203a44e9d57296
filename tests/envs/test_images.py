"""Camera observations (`obs_mode="image"`): robomimic's keys, shapes and dtype on every task, the same
key giving the same first image, the in-hand camera seeing the object once the gripper is above it,
and the agent view seeing the arm."""

import jax
import numpy as np
import pytest

from soe_jax.envs.registry import env_names, make_env
from soe_jax.experts import collect
from soe_jax.experts import registry as expert_registry
from tests.render.test_render import needs_egl

pytestmark = needs_egl
# robomimic's image keys: transport's shoulder and wrist cameras, the agent view and wrist camera otherwise.
IMAGE_KEYS = {
  "transport": (
    "shouldercamera0_image",
    "shouldercamera1_image",
    "robot0_eye_in_hand_image",
    "robot1_eye_in_hand_image",
  )
}


@pytest.mark.parametrize("task", [t if t == "lift" else pytest.param(t, marks=pytest.mark.slow) for t in env_names()])
def test_image_obs_have_robomimics_keys_shapes_and_dtype(task):
  env = make_env(task, obs_mode="image", backend="mujoco")
  reset = jax.jit(jax.vmap(env.reset))
  a, b = reset(jax.random.split(jax.random.PRNGKey(3), 2)), reset(jax.random.split(jax.random.PRNGKey(3), 2))
  assert env.image_keys == IMAGE_KEYS.get(task, ("agentview_image", "robot0_eye_in_hand_image"))
  for key in env.image_keys:
    assert a.obs[key].shape == (2, 84, 84, 3) and a.obs[key].dtype == np.uint8
    np.testing.assert_array_equal(a.obs[key], b.obs[key])  # the same key, the same first image
    assert not np.array_equal(a.obs[key][0], a.obs[key][1])  # other start states, other pictures
  assert "object" in a.obs and a.obs["robot0_eef_pos"].shape == (2, 3)  # the low-dim keys stay
  env.renderer.close()


def test_unknown_observation_modes_list_the_known_ones():
  with pytest.raises(ValueError, match="unknown observation mode 'rgb'; known observation modes: low_dim, image"):
    make_env("lift", obs_mode="rgb")


def _changed_mask(a: np.ndarray, b: np.ndarray) -> np.ndarray:
  """(H, W) bool: the pixels that differ visibly between two images."""
  return np.abs(a.astype(int) - b.astype(int)).max(-1) > 24


@pytest.mark.slow
@pytest.mark.parametrize("task", ["lift", "can", "square"])
def test_wrist_camera_sees_the_object_agent_view_sees_the_arm(task):
  """The wrist camera sees the object from above, and the agent view sees the arm."""
  env = make_env(task, obs_mode="image", backend="mujoco")
  demo = collect.run_demos(
    env, expert_registry.make_expert(task), jax.random.split(jax.random.PRNGKey(0), 1), progress=False
  )
  eef, obj = demo["obs"]["robot0_eef_pos"][0], demo["obs"]["object"][0, :, :3]
  # The demonstration's first step with the gripper over the object, within 8 cm above it.
  t = int(np.flatnonzero(eef[:, 2] - obj[:, 2] < 0.08)[0])
  nq = env.mj_model.nq
  qpos = demo["states"][0, t, 1 : 1 + nq]
  without_object = qpos.copy()
  without_object[9:12] = (0.0, 0.0, -2.0)  # under the floor
  arm_turned = qpos.copy()
  arm_turned[0] += 0.6
  images = env.renderer.render(np.stack([qpos, without_object, arm_turned]))
  wrist, agent = images["robot0_eye_in_hand"], images["agentview"]
  seen = _changed_mask(wrist[0], wrist[1])
  assert seen.mean() > 0.02  # the object covers a part of the wrist view (Lift's 4 cm cube: about 4%)
  assert 21 < np.flatnonzero(seen.any(0)).mean() < 63  # between the fingers, in the middle half
  assert _changed_mask(agent[0], agent[2]).mean() > 0.01  # turning the arm changes the agent view
  env.renderer.close()


def test_the_video_command_names_the_tasks_cameras():
  from soe_jax.envs import manipulation
  from soe_jax.experiment import video

  assert video.CAMERAS == manipulation.CAMERAS


def test_images_drawn_from_an_episodes_states_are_those_observed():
  """Images drawn from an episode's states are the ones its steps observed."""
  from soe_jax.data.episodes import draw_images
  from soe_jax.envs import manipulation

  env = make_env("lift", obs_mode="image", backend="mujoco")
  reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
  state = reset(jax.random.split(jax.random.PRNGKey(4), 2))
  rng = np.random.default_rng(0)
  seen, states = {k: [] for k in manipulation.IMAGE_KEYS}, []
  for _ in range(3):
    for k in seen:
      seen[k].append(np.asarray(state.obs[k]))
    states.append(env.physics.sim_state_float64(env.physics.sim_state(state.pipeline_state)))
    action = np.asarray(state.obs["robot0_eef_pos"])
    action = np.concatenate([action + rng.normal(0, 0.02, action.shape), np.tile([1, 0, 0, 0, 1, 0, -1], (2, 1))], -1)
    state = step(state, action.astype(np.float32))
  episodes = [dict(obs={}, states=np.stack(states)[:, i]) for i in range(2)]
  draw_images(env, episodes, manipulation.IMAGE_KEYS)
  for i, ep in enumerate(episodes):
    for k in manipulation.IMAGE_KEYS:
      np.testing.assert_array_equal(ep["obs"][k], np.stack(seen[k])[:, i])
  with pytest.raises(ValueError, match="without simulator states"):
    draw_images(env, [dict(obs={})], manipulation.IMAGE_KEYS)
  env.renderer.close()

"""The C-engine backend: bit-exact float64 state through JAX, determinism, batching, wrappers."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from soe_jax import geometry
from soe_jax.envs import agreement
from soe_jax.envs.registry import env_names, make_env
from soe_jax.envs.wrappers import wrap_env


def _hold(obs):
  return jnp.concatenate(
    [obs["robot0_eef_pos"], geometry.mat_to_rot6d(obs["robot0_eef_rot"].reshape(3, 3)), jnp.array([1.0])]
  )


def test_state_is_float64_bytes_and_steps_are_deterministic(jitted_env):
  env, reset, step = jitted_env("square")
  state = reset(jax.random.PRNGKey(0))
  s64 = env.physics.float64_state(state.pipeline_state)
  assert s64.dtype == np.float64 and s64.shape == (env.physics.nstate,)
  np.testing.assert_array_equal(s64[1 : 1 + env.mj_model.nq], np.asarray(state.pipeline_state.qpos, np.float64))
  action = _hold(state.obs)
  a, b = state, state
  for _ in range(5):
    a, b = step(a, action), step(b, action)
  np.testing.assert_array_equal(a.pipeline_state.raw, b.pipeline_state.raw)
  # Carried at full precision: the float64 state holds more than the float32 view shows.
  s64 = env.physics.float64_state(a.pipeline_state)
  assert np.any(s64[1 : 1 + env.mj_model.nq] != s64[1 : 1 + env.mj_model.nq].astype(np.float32))


def test_batched_step_is_independent_of_batch_position(jitted_env):
  env, reset, step = jitted_env("lift")
  keys = jax.random.split(jax.random.PRNGKey(5), 8)
  batch_reset, batch_step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
  start = batch_reset(keys)
  actions = jax.vmap(_hold)(start.obs)
  out = batch_step(start, actions)
  perm = np.array([3, 7, 0, 5, 1, 6, 2, 4])
  permuted = batch_step(jax.tree.map(lambda x: x[perm], start), actions[perm])
  # Bit-identical whichever slot (and so whichever C thread) an environment lands in.
  np.testing.assert_array_equal(permuted.pipeline_state.raw, out.pipeline_state.raw[perm])
  # A single environment stepped alone agrees up to float32 rounding of the vectorised IK.
  single = step(reset(keys[2]), actions[2])
  np.testing.assert_allclose(single.pipeline_state.qpos, out.pipeline_state.qpos[2], atol=1e-5)


def test_wrapped_env_counts_steps_and_auto_resets_to_start():
  env = make_env("lift")
  wrapped = wrap_env(env, episode_length=3)
  keys = jax.random.split(jax.random.PRNGKey(0), 4)
  state = jax.jit(wrapped.reset)(keys)
  first = state.pipeline_state.qpos
  step = jax.jit(wrapped.step)
  actions = jax.vmap(_hold)(state.obs)
  for _ in range(3):
    state = step(state, actions)
  assert np.all(np.asarray(state.done) == 1)
  # Done at the episode length: the auto-reset put every environment back to its start state.
  np.testing.assert_array_equal(state.pipeline_state.qpos, first)
  assert np.all(np.asarray(state.info["steps"]) == 3)


@pytest.mark.slow
@pytest.mark.parametrize("task", env_names())
def test_backends_agree_on_a_scripted_motion(task):
  """Same start state, same 50 actions: the end-effector paths on MJX-JAX (its accelerator scene, one
  environment without vmap: vmap is slow on a CPU) and the C engine agree."""
  paths = {}
  for backend in ("mujoco", "mjx"):
    env = make_env(task, backend=backend, mjx_impl="jax")
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))
    obs0 = state.obs

    def body(s, t):
      s = env.step(s, agreement.scripted_motion(obs0, t))
      return s, s.obs["robot0_eef_pos"]

    _, path = jax.jit(lambda s: jax.lax.scan(body, s, jnp.arange(50)))(state)
    paths[backend] = np.asarray(path)
  gap = np.linalg.norm(paths["mujoco"] - paths["mjx"], axis=-1)
  assert gap.max() < 0.005, gap.max()


def test_engine_instabilities_are_counted_not_silent(jitted_env, tmp_path, monkeypatch):
  monkeypatch.chdir(tmp_path)  # MuJoCo writes MUJOCO_LOG.TXT into the working directory
  env, reset, step = jitted_env("lift")
  state = reset(jax.random.PRNGKey(0))
  s64 = env.physics.float64_state(state.pipeline_state).copy()
  s64[1 + env.mj_model.nq + 9] = 1e30  # the cube's velocity blows up
  exploded = state.replace(pipeline_state=state.pipeline_state.replace(raw=jnp.asarray(s64.view(np.uint32))))
  before = env.physics.instabilities
  jax.block_until_ready(step(exploded, _hold(state.obs)).obs)
  assert env.physics.instabilities > before

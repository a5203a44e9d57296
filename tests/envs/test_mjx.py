"""The MJX backend's implementations (MJX-JAX, MuJoCo Warp on the CPU), its settings and buffers."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from soe_jax.envs import agreement, backends, physics
from soe_jax.envs.registry import make_env
from soe_jax.envs.wrappers import wrap_env
from soe_jax.experiment import presets, validation
from soe_jax.experts import collect
from soe_jax.experts.registry import expert_names, make_expert


def _warp():
  pytest.importorskip("warp", reason="warp-lang is not installed: pip install -e '.[gpu]'")


def test_unknown_implementation_lists_the_known_ones():
  with pytest.raises(ValueError, match="known MJX implementations: auto, jax, warp"):
    make_env("lift", backend="mjx", mjx_impl="cuda")


def test_warp_without_warp_lang_says_how_to_install_it(monkeypatch):
  monkeypatch.setattr(backends, "warp_installed", lambda: False)
  with pytest.raises(ValueError, match=r"pip install 'soe_jax\[gpu\]'"):
    backends.resolve_mjx_impl("warp")
  assert backends.resolve_mjx_impl("auto") == "jax"  # auto falls back to MJX-JAX


def test_config_problems_name_bad_mjx_fields():
  config = presets.base_config("lift", 3)
  config.env.backend, config.env.mjx_impl, config.env.mjx_settings = "mjx", "tpu", "iterations=ten"
  found = "\n".join(validation.problems(config))
  assert "unknown MJX implementation 'tpu'" in found
  assert "bad env.mjx_settings item 'iterations=ten': iterations takes an integer" in found
  config.env.mjx_impl, config.env.mjx_settings = "jax", "solver=newton"
  assert "bad env.mjx_settings item 'solver=newton'; known settings: iterations, ls_iterations, cone" in "\n".join(
    validation.problems(config)
  )


def test_settings_replace_solver_options_for_mjx_alone():
  task_default = {"iterations": 10}
  assert backends.parse_settings("", task_default) == task_default
  assert backends.parse_settings("engine", task_default) == {}
  settings = backends.parse_settings("iterations=5,ls_iterations=8,cone=pyramidal", task_default)
  assert settings == {"iterations": 5, "ls_iterations": 8, "cone": "pyramidal"}
  with pytest.raises(ValueError, match="unknown cone 'round'"):
    backends.parse_settings("cone=round", {})
  env = make_env("lift", backend="mujoco")
  m = physics.apply_settings(env.mj_model, settings)
  assert (m.opt.iterations, m.opt.ls_iterations, m.opt.cone) == (5, 8, physics.CONES["pyramidal"])
  # The C engine's model keeps the scene's options.
  assert (env.mj_model.opt.iterations, env.mj_model.opt.cone) == (100, physics.CONES["elliptic"])


@pytest.mark.slow
@pytest.mark.parametrize("task", expert_names())
def test_warp_buffers_cover_the_demonstrators_contacts(task):
  """Warp preallocates contacts and constraint rows per environment: the task's sizes cover the most
  any state of its scripted demonstrations has (in the MJX scene's settings), with a margin of 1.5."""
  env = make_env(task, backend="mujoco")
  batch = collect.run_demos(env, make_expert(task), jax.random.split(jax.random.PRNGKey(0), 16), progress=False)
  settings = backends.parse_settings("", env.mjx_settings)
  peak = agreement.peak_usage(physics.apply_settings(env.mj_model, settings), batch["states"], batch["length"])
  assert 1.5 * peak["contacts"] <= env.mjx_contacts, peak
  assert 1.5 * peak["constraints"] <= env.mjx_constraints, peak


@pytest.mark.slow
def test_warp_follows_the_engine_and_auto_resets():
  """MuJoCo Warp on the CPU: the lift end-effector path within 1 cm of the C engine's over 50 scripted
  steps (the MJX scene's settings), and brax-style auto-reset that leaves Warp's shared contact buffer
  alone."""
  _warp()
  keys = jax.random.split(jax.random.PRNGKey(0), 2)
  env = make_env("lift", backend="mjx", mjx_impl="warp", mjx_max_batch=2)
  gap = np.linalg.norm(agreement.eef_paths(env, keys) - agreement.eef_paths(make_env("lift"), keys), axis=-1)
  assert gap.max() < 0.01, gap.max()
  wrapped = wrap_env(env, episode_length=3)
  state = jax.jit(wrapped.reset)(keys)
  first = state.pipeline_state.qpos
  step = jax.jit(wrapped.step)
  action = jax.vmap(agreement.scripted_motion, in_axes=(0, None))(state.obs, 10)
  for _ in range(3):
    state = step(state, action)
  assert np.all(np.asarray(state.done) == 1) and np.all(np.asarray(state.info["steps"]) == 3)
  np.testing.assert_array_equal(state.pipeline_state.qpos, first)
  assert state.pipeline_state.raw._impl.contact__type.shape == (2 * env.mjx_contacts,)  # not batched


@pytest.mark.slow
def test_warp_running_out_of_contacts_is_an_error():
  """Two contacts per environment cannot hold a cube resting on the table: Warp drops the rest, and
  the backend refuses to carry on."""
  _warp()
  env = make_env("lift", backend="mjx", mjx_impl="warp", mjx_max_batch=2)
  env.physics = physics.MjxBackend(env.mj_model, env.config.nsubsteps, impl="warp", contacts=1, max_batch=2)
  keys = jax.random.split(jax.random.PRNGKey(0), 2)
  state = jax.jit(jax.vmap(env.reset))(keys)
  action = jax.vmap(agreement.scripted_motion, in_axes=(0, None))(state.obs, 0)
  state = jax.jit(jax.vmap(env.step))(state, action)
  with pytest.raises(RuntimeError, match="ran out of preallocated contacts"):
    env.physics.check(state.pipeline_state)
  with pytest.raises(ValueError, match="more than env.mjx_max_batch=2"):
    env.physics.check(jax.tree.map(lambda x: jnp.concatenate([x, x]), state.pipeline_state))

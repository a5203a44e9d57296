"""Shared fixtures: the persistent compilation cache, and environments compiled once per session."""

import functools
import os

os.environ.setdefault("MUJOCO_GL", "egl")  # headless rendering; must precede the first import of mujoco

import jax
import pytest

from soe_jax import compile_cache

compile_cache.enable()


@functools.cache
def _env(name: str, backend: str = "mujoco", episode_length: int = 400):
  from soe_jax.envs import make_env

  return make_env(name, backend=backend, episode_length=episode_length)


@pytest.fixture(scope="session")
def task_env():
  """`task_env(name, backend="mujoco", episode_length=400) -> env`, one object per settings, so tests
  share its compiled programs."""
  return _env


@functools.cache
def _jitted(name: str, backend: str = "mujoco"):
  env = _env(name, backend)
  return env, jax.jit(env.reset), jax.jit(env.step)


@pytest.fixture(scope="session")
def jitted_env():
  """`jitted_env(name, backend="mujoco") -> (env, jit(reset), jit(step))`, shared across tests."""
  return _jitted


@pytest.fixture(scope="session")
def smoke_run(tmp_path_factory):
  """A finished two-round `lift:smoke,soe` run: (runs root, config, workdir, summary)."""
  from configs import lift as lift_config
  from soe_jax import loop

  root = tmp_path_factory.mktemp("runs")
  config = lift_config.get_config("smoke,soe")
  workdir = str(root / "lift-soe")
  summary = loop.run(config, workdir, progress=False)
  return root, config, workdir, summary

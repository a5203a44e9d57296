"""Shared fixtures: the persistent compilation cache, and environments compiled once per session."""

import functools

import jax
import pytest

from soe_jax import compile_cache

compile_cache.enable()


@functools.lru_cache(maxsize=None)
def _env(name: str, backend: str = "mujoco"):
  from soe_jax.envs import make_env
  return make_env(name, backend=backend)


@functools.lru_cache(maxsize=None)
def _jitted(name: str, backend: str = "mujoco"):
  env = _env(name, backend)
  return env, jax.jit(env.reset), jax.jit(env.step)


@pytest.fixture(scope="session")
def jitted_env():
  """`jitted_env(name, backend="mujoco") -> (env, jit(reset), jit(step))`, shared across tests."""
  return _jitted

"""Shared fixtures: the persistent compilation cache, environments compiled once per session, and the
toy task (`experiment/toy.py`): registered for a test (`toy_task`), and a finished toy run shared by the
session (`toy_run`)."""

import functools

import jax
import pytest

from soe_jax.runtime import compile_cache

compile_cache.enable()


def _mappings() -> int:
  with open("/proc/self/maps") as f:
    return sum(1 for _ in f)


def _mapping_limit() -> int | None:
  try:
    with open("/proc/sys/vm/max_map_count") as f:
      return int(f.read())
  except OSError:  # not Linux
    return None


_MAPPING_LIMIT = _mapping_limit()


@pytest.fixture(autouse=True)
def _release_compiled_programs():
  """Free the compiled programs once they hold too many memory mappings. XLA maps each CPU
  executable's code into a few dozen regions and keeps them while its jitted function lives; over the
  whole suite they would reach the kernel's limit per process (vm.max_map_count, 65530 by default),
  where the next compile crashes the process. Past 40% of the limit, the programs are dropped after
  the test (those used again recompile, from the persistent cache)."""
  yield
  limit = _MAPPING_LIMIT
  if limit and _mappings() > 0.4 * limit:
    jax.clear_caches()
    assert _mappings() < 0.4 * limit, f"{_mappings()} memory mappings after clearing, of at most {limit}"


@functools.cache
def _env(name: str, backend: str = "mujoco", episode_length: int | None = None):
  from soe_jax.envs.registry import make_env

  return make_env(name, backend=backend, **({} if episode_length is None else {"episode_length": episode_length}))


@pytest.fixture(scope="session")
def task_env():
  """`task_env(name, backend="mujoco", episode_length=None) -> env` (None: the task's own), one object
  per settings, so tests share its compiled programs."""
  return _env


@functools.cache
def _jitted(name: str, backend: str = "mujoco"):
  env = _env(name, backend)
  return env, jax.jit(env.reset), jax.jit(env.step)


@pytest.fixture(scope="session")
def jitted_env():
  """`jitted_env(name, backend="mujoco") -> (env, jit(reset), jit(step))`, shared across tests."""
  return _jitted


@pytest.fixture
def toy_task():
  """The toy task and its demonstrator registered as "toy" for the test."""
  from tests.experiment import toy

  with toy.registered():
    yield


@pytest.fixture(scope="session")
def toy_run(tmp_path_factory):
  """A finished two-round `toy:smoke,soe` run: (runs root, config, workdir)."""
  from soe_jax.experiment import loop
  from tests.experiment import toy

  root = tmp_path_factory.mktemp("toy_runs")
  config = toy.get_config("smoke,soe")
  workdir = str(root / "toy-soe")
  with toy.registered():
    loop.run(config, workdir, progress=False)
  return root, config, workdir


@pytest.fixture(scope="session")
def smoke_run(tmp_path_factory):
  """A finished two-round `lift:smoke,soe` run, with a video of each phase's first episode: (runs root,
  config, workdir, summary)."""
  from configs import lift as lift_config
  from soe_jax.analysis import report
  from soe_jax.experiment import loop

  root = tmp_path_factory.mktemp("runs")
  config = lift_config.get_config("smoke,soe")
  config.log.videos = 1
  workdir = str(root / "lift-soe")
  loop.run(config, workdir, progress=False)
  return root, config, workdir, report.write(workdir)


@pytest.fixture
def expert_round(tmp_path):
  """`run(config)`: one round of `config` with the demonstrator as the exploration strategy (it
  succeeds from every start state, so each is kept) in tmp_path/run, checked to have kept every state
  and re-fitted on them -> (workdir, RunDir, kept episodes)."""

  def run(config):
    import json
    import os

    from soe_jax.analysis import report
    from soe_jax.data import hdf5
    from soe_jax.experiment import loop, presets
    from soe_jax.experiment.rundir import RunDir

    config.explore.strategy = presets.strategy_config("expert")
    config.rounds.num_rounds = 1
    workdir = str(tmp_path / "run")
    loop.run(config, workdir, progress=False)
    summary = report.write(workdir)
    run_dir = RunDir.open(workdir)
    kept, _ = hdf5.read_episodes(run_dir.data_path(1))
    assert len(kept) == summary["kept"] == config.explore.num_start_states
    fits = [json.loads(line) for line in open(os.path.join(workdir, "metrics.jsonl")) if '"phase": "fit"' in line]
    assert [f["num_episodes"] for f in fits] == [config.data.num_demos, config.data.num_demos + len(kept)]
    return workdir, run_dir, kept

  return run

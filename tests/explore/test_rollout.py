"""The rollout engine: observation history and chunk bookkeeping, determinism, slices, and the scripted
demonstrator run through it as a policy. The engine's logic runs on the toy task (`experiment/toy.py`:
its programs compile once and come back from the persistent cache); the demonstrator's on Lift."""

import dataclasses
import functools

import jax
import numpy as np
import pytest

from configs import lift as lift_config
from soe_jax.envs.registry import make_env
from soe_jax.experiment import task
from soe_jax.experts.collect import run_demos
from soe_jax.experts.registry import make_expert
from soe_jax.explore import registry, rollout
from soe_jax.policies import normalizer as normalizer_lib
from soe_jax.policies.agent import Agent
from tests.experiment import toy

pytestmark = pytest.mark.usefixtures("toy_task")  # (a strategy may ask for the task's demonstrator)


def _setup(env, config):
  """`env`, the policy of `config` and an untrained agent of it."""
  policy = task.policy(config)
  rng = np.random.default_rng(0)
  demo_like = rng.uniform(-0.2, 1.0, (100, policy.obs_dim))
  # Commanded positions within 10 cm of the origin in x and y: Lift's cube is not lifted, the toy's goal
  # (x 0.21-0.31 m) not reached.
  actions = np.concatenate(
    [rng.uniform(-0.1, 0.1, (100, 2)), rng.uniform(0.85, 1.0, (100, 1)), rng.uniform(-1, 1, (100, 7))], 1
  )
  params = jax.jit(policy.init)(jax.random.PRNGKey(0))  # compiled: eager initialisation takes seconds
  agent = Agent(policy, params, normalizer_lib.fit(demo_like, actions))
  return env, policy, agent


EPISODE = 20  # not a multiple of n_action_steps (8); every short test shares one compiled program


@functools.cache
def _toy():
  """The toy task's env (20-step episodes), its smoke policy and an untrained agent, one per session."""
  return _setup(make_env(toy.NAME, episode_length=EPISODE), toy.get_config("smoke"))


def test_rollouts_are_a_pure_function_of_the_keys():
  env, policy, agent = _toy()
  keys = jax.random.split(jax.random.PRNGKey(1), 2)
  soe = registry.make_strategy("soe")
  a = rollout.rollout(env, agent, soe, keys, jax.random.PRNGKey(2), progress=False)
  b = rollout.rollout(env, agent, soe, keys, jax.random.PRNGKey(2), progress=False)
  for k in ("obs", "actions", "eef_pos", "qpos", "length", "success"):
    np.testing.assert_array_equal(a[k], b[k])
  np.testing.assert_array_equal(a["aux"]["z"], b["aux"]["z"])
  c = rollout.rollout(env, agent, soe, keys, jax.random.PRNGKey(3), progress=False)
  np.testing.assert_array_equal(a["obs"][:, 0], c["obs"][:, 0])  # same start states
  assert not np.allclose(a["actions"], c["actions"])  # other exploration noise


def test_records_history_episode_length_and_slices():
  env, policy, agent = _toy()
  keys = jax.random.split(jax.random.PRNGKey(1), 4)
  out = rollout.rollout(
    env, agent, registry.make_strategy("dp"), keys, jax.random.PRNGKey(0), slice_size=2, progress=False
  )
  assert out["obs"].shape == (4, EPISODE, policy.obs_dim) and out["actions"].shape == (4, EPISODE, 10)
  assert out["eef_pos"].shape == (4, EPISODE + 1, 1, 3) and out["aux"] == {}
  np.testing.assert_array_equal(out["length"], EPISODE)  # an untrained policy does not reach the goal
  assert not out["success"].any()
  # Every slice starts from its own keys' start states.
  start = jax.vmap(env.reset)(keys)
  np.testing.assert_allclose(out["obs"][:, 0, :3], start.obs["robot0_eef_pos"], atol=1e-6)
  np.testing.assert_allclose(out["qpos"][:, 0], start.pipeline_state.qpos, atol=1e-6)
  # robomimic's states: the engine's [time, qpos, qvel] before each action, as the task's physics
  # records them (MuJoCo's float64 bits: envs/test_images.py), exactly.
  first = rollout.initial_carry(env, policy.n_obs_steps, keys).state.pipeline_state  # the rollout's own reset
  size = 1 + first.qpos.shape[-1] + first.qvel.shape[-1]
  assert out["states"].dtype == np.float64 and out["states"].shape == (4, EPISODE, size)
  np.testing.assert_array_equal(out["states"][:, 0], env.physics.sim_state_float64(env.physics.sim_state(first)))
  assert np.all(np.diff(out["states"][:, :, 0], axis=1) > 0)  # time advances every control step
  np.testing.assert_array_equal(out["next_obs"][:, :-1], out["obs"][:, 1:])  # the observation after each action
  np.testing.assert_allclose(out["eef_pos"][:, 1:-1, 0], out["obs"][:, 1:, :3], atol=1e-6)
  # Each observation is followed by the action taken from it: the first chunk is 8 steps long, then
  # the next decision starts from the observation after them.
  assert not np.allclose(out["actions"][:, 7], out["actions"][:, 8])


@pytest.mark.slow
def test_the_demonstrator_in_the_engine_keeps_its_success_rate(task_env):
  """The scripted demonstrator, run through the engine as a policy, reproduces its success rate."""
  env, policy, agent = _setup(task_env("lift"), lift_config.get_config("smoke"))
  keys = jax.random.split(jax.random.PRNGKey(7), 8)
  demos = run_demos(env, make_expert("lift"), keys, progress=False)
  out = rollout.rollout(env, agent, registry.make_strategy("expert", env), keys, jax.random.PRNGKey(0), progress=False)
  assert abs(out["success"].mean() - demos["success"].mean()) <= 1 / 8
  assert out["success"].mean() >= 0.875
  ok = out["success"]
  assert (out["length"][ok] < 400).all()
  # After success nothing more is recorded as part of the episode: the last step is the lifting one.
  last = out["length"][ok] - 1
  cube_z = out["obs"][ok, last, 9 + 2]
  assert (cube_z > 0.8).all()


# expert: above (on Lift); soe_steer compiles its proposals in seconds on the toy task (20 s on Lift).
@pytest.mark.parametrize("name", [n for n in registry.strategy_names() if n != "expert"])
def test_every_strategy_runs_in_the_engine(name):
  env, policy, agent = _toy()
  keys = jax.random.split(jax.random.PRNGKey(5), 2)
  strat = registry.make_strategy(name, env)
  if name == "soe_steer":
    strat = dataclasses.replace(strat, dims=(0, 1), num_proposals=4, num_choices=2)
  out = rollout.rollout(env, agent, strat, keys, jax.random.PRNGKey(0), progress=False)
  assert out["actions"].shape == (2, EPISODE, 10) and np.isfinite(out["actions"]).all()
  if name == "soe_steer":
    assert out["aux"]["steered"].shape == (2, 3) and out["aux"]["steered"].all()
    assert set(np.unique(out["aux"]["dim"])) <= {0, 1}

"""Quaternion inputs are continuous along every motion (scripted episodes and policy rollouts on every
task), and files recorded with another sign convention read back in this one."""

import functools

import jax
import numpy as np
import pytest

from soe_jax.data import hdf5
from soe_jax.envs import rotations
from soe_jax.envs.observations import policy_obs
from soe_jax.experiment import presets
from soe_jax.experiment import task as task_lib
from soe_jax.experts import collect
from soe_jax.experts.registry import expert_names, make_expert
from soe_jax.explore import registry, rollout
from soe_jax.policies import normalizer as normalizer_lib
from soe_jax.policies.agent import Agent


def _quat_slices(env):
  """The policy observation's quaternion parts, as slices."""
  out, start = [], 0
  for kind, size in env.obs_layout:
    if "quat" in kind:
      out.append(slice(start, start + size))
    start += size
  return out


def _jumps(env, obs, length):
  """obs (N, H, D) policy observations -> (step-to-step change of each quaternion part, the same up to
  sign: the rotation itself), over the frames of each episode."""
  jump, motion = [], []
  for i, n in enumerate(length):
    for s in _quat_slices(env):
      q = obs[i, : int(n), s]
      jump.append(np.linalg.norm(q[1:] - q[:-1], axis=-1))
      motion.append(np.minimum(jump[-1], np.linalg.norm(q[1:] + q[:-1], axis=-1)))
  return np.concatenate(jump), np.concatenate(motion)


@functools.cache
def _params(policy):
  return jax.jit(policy.init)(jax.random.PRNGKey(0))  # compiled: eager initialisation takes seconds


@functools.cache
def _demos(task, jitted):
  env = jitted(task)[0]
  keys = jax.random.split(jax.random.PRNGKey(3), 3)
  return env, collect.run_demos(env, make_expert(task), keys, progress=False)


# Lift's in the default suite; the others' whole demonstrations take 10-20 s each: slow.
@pytest.mark.parametrize(
  "task", [t if t == "lift" else pytest.param(t, marks=pytest.mark.slow) for t in expert_names()]
)
def test_quaternions_are_continuous_along_scripted_episodes(task, jitted_env):
  env, batch = _demos(task, jitted_env)
  obs = np.asarray(policy_obs(batch["obs"], xp=np))
  assert batch["length"].min() > 30  # whole episodes: approach, grasp, move
  jump, _ = _jumps(env, obs, batch["length"])
  assert jump.max() < 0.2
  # The hand's quaternion stays in its hemisphere, far from the boundary where signs would flip.
  hand = obs[..., 3:7] @ np.asarray(rotations.wxyz_to_xyzw(env.hand_reference))
  assert hand[:, : int(batch["length"].min())].min() > 0.5


@pytest.mark.slow
@pytest.mark.parametrize("task", expert_names())
def test_quaternions_are_continuous_along_policy_rollouts(task, jitted_env, task_env):
  env = task_env(task, episode_length=20)  # lift's: the rollout tests' environment and programs
  config = presets.apply_presets(presets.base_config(task, 4), "smoke")
  policy = task_lib.policy(config)
  _, batch = _demos(task, jitted_env)
  frames = np.asarray(policy_obs(batch["obs"], xp=np))[:, :30]
  actions = batch["actions"][:, :30]
  norm = normalizer_lib.fit(
    frames.reshape(-1, policy.obs_dim),
    actions.reshape(-1, actions.shape[-1]),
    obs_min_span=env.obs_min_span,
    num_robots=env.num_robots,
  )
  agent = Agent(policy, _params(policy), norm)
  keys = jax.random.split(jax.random.PRNGKey(4), 4)
  strategy = registry.make_strategy("soe")
  out = rollout.rollout(env, agent, strategy, keys, jax.random.PRNGKey(0), progress=False)
  jump, motion = _jumps(env, out["obs"], out["length"])
  assert motion.max() > 0.01  # the untrained policy turns the hand
  # Never a sign flip (the change is the rotation's own), and below 0.2 but for the rare step in which
  # the untrained policy knocks an object and turns it faster than that.
  np.testing.assert_array_equal(jump, motion)
  assert (jump < 0.2).mean() > 0.95


@pytest.mark.slow
def test_other_quaternion_signs_read_back_in_tasks_convention(tmp_path, jitted_env):
  """A file with other quaternion signs reads back in the task's sign convention."""
  env, batch = _demos("square", jitted_env)
  episodes = collect.split_episodes(batch)
  rng = np.random.default_rng(0)
  flipped = []
  for e in episodes:  # robosuite's w >= 0 everywhere, then random signs on top
    obs = {k: v.copy() for k, v in e["obs"].items()}
    for q in (obs["robot0_eef_quat"], obs["object"][:, 3:7], obs["object"][:, 10:14]):
      q *= np.where(q[:, 3:] < 0, -1.0, 1.0) * rng.choice([-1.0, 1.0], (len(q), 1))
    flipped.append(dict(e, obs=obs))
  hdf5.write_episodes(str(tmp_path / "other.hdf5"), flipped, dict(env_name="square"))
  hdf5.write_episodes(str(tmp_path / "ours.hdf5"), episodes, dict(env_name="square"))
  for name in ("other", "ours"):
    read, _ = hdf5.read_episodes(str(tmp_path / f"{name}.hdf5"), env)
    for got, want in zip(read, episodes):
      for k in ("robot0_eef_quat", "object"):
        np.testing.assert_allclose(got["obs"][k], want["obs"][k], atol=1e-5)

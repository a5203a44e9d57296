"""The scripted demonstrators run batched under jit and solve the task; variety and determinism."""

import jax
import numpy as np
import pytest

from soe_jax.experts import collect
from soe_jax.experts.registry import EXPERTS, make_expert


def test_lift_demonstrations_succeed_and_vary(jitted_env):
  env, _, _ = jitted_env("lift")
  keys = jax.random.split(jax.random.PRNGKey(0), 8)
  batch = collect.run_demos(env, make_expert("lift"), keys, progress=False)
  assert batch["success"].all()
  assert batch["length"].std() > 0  # randomised timing
  episodes = collect.split_episodes(batch)
  assert [e["actions"].shape[0] for e in episodes] == list(batch["length"])
  # Smooth: commanded positions move less than 3 cm per step.
  for e in episodes:
    assert np.abs(np.diff(e["actions"][:, :3], axis=0)).max() < 0.03
  # robomimic's fields: states [time, qpos, qvel] in float64, and each step's next observation.
  e, nq, nv = episodes[0], env.mj_model.nq, env.mj_model.nv
  assert e["states"].dtype == np.float64 and e["states"].shape == (len(e["actions"]), 1 + nq + nv)
  assert e["states"][0, 0] == 0.0 and np.all(np.diff(e["states"][:, 0]) > 0)  # time from the reset on
  for k in e["obs"]:
    np.testing.assert_array_equal(e["next_obs"][k][:-1], e["obs"][k][1:])
  again = collect.run_demos(env, make_expert("lift"), keys, progress=False)
  np.testing.assert_array_equal(batch["actions"], again["actions"])


def test_unknown_expert_lists_known_ones():
  with pytest.raises(ValueError, match="known scripted demonstrators: can, lift, square"):
    make_expert("transport")


@pytest.mark.slow
@pytest.mark.parametrize("task", [t for t in EXPERTS.names() if t != "lift"])  # lift: above
def test_demonstrators_succeed(task, jitted_env):
  env, _, _ = jitted_env(task)
  batch = collect.run_demos(env, make_expert(task), jax.random.split(jax.random.PRNGKey(0), 16), progress=False)
  assert batch["success"].mean() >= 0.9

"""Transport, two arms, through the whole experiment (`configs/transport.py:smoke` with the
demonstrator as the exploration strategy, so that exploration keeps episodes): both robots' keys in
the kept episodes, the re-fit on them, a checkpoint that acts with 20 numbers, the steering page's
paths for both arms, and the export."""

import h5py
import jax
import numpy as np
import pytest

from configs import transport as transport_config
from soe_jax.data import export
from soe_jax.envs import observations
from soe_jax.envs import registry as env_registry
from soe_jax.policies import agent as agent_lib
from soe_jax.train import checkpoint


@pytest.mark.slow
def test_a_two_arm_round_keeps_refits_acts_and_exports(tmp_path, expert_round):
  config = transport_config.get_config("smoke")
  workdir, run, kept = expert_round(config)
  for ep in kept:
    t = len(ep["actions"])
    assert ep["actions"].shape == (t, 20)
    for k, size in observations.policy_obs_sizes(41, 2).items():
      assert ep["obs"][k].shape == (t, size), k
  loaded = checkpoint.load(run.ckpt_dir(1))
  env = env_registry.env_from_config(config.env)
  state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(7), 1))
  hist = agent_lib.initial_history(observations.policy_obs(state.obs), 2)
  actions = np.asarray(loaded.agent.act(hist, jax.random.PRNGKey(1)))
  assert actions.shape == (1, config.policy.n_action_steps, 20) and np.isfinite(actions).all()
  from soe_jax.steer import session

  steering = session.SteeringSession(workdir)
  try:
    view = steering.proposals(steering.dims[0])
    assert len(view["paths"]) == 2 and all(len(p) == 1 for p in view["paths"])  # each arm's hand, at the start
    assert [len(p["paths"]) for p in view["proposals"]] == [2] * steering.steer.num_choices
    assert all(len(q) == config.policy.n_action_steps for p in view["proposals"] for q in p["paths"])
  finally:
    steering.close()
  out = str(tmp_path / "data.hdf5")
  export.write(out, "robomimic", *run.fit_sets())
  with h5py.File(out) as f:
    demo = f["data/demo_5"]  # a kept episode (after the 4 demonstrations)
    assert demo["obs"]["robot1_eef_pos"].shape == (demo.attrs["num_samples"], 3)
    assert demo["obs"]["object"].shape == (demo.attrs["num_samples"], 41)

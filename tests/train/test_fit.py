"""The compiled fit phase, EMA, data parallelism on forced CPU devices, and checkpoints."""

import json
import os
import subprocess
import sys

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from configs import lift
from soe_jax.data import buffer as buffer_lib
from soe_jax.experiment import task
from soe_jax.policies import normalizer
from soe_jax.policies.agent import Agent
from soe_jax.policies.policy import make_policy
from soe_jax.train import checkpoint, fit, train_state

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _setup(ema=True):
  config = lift.get_config("smoke")
  rng = np.random.default_rng(0)
  n, length, obs_dim = 6, 40, 19
  t = np.arange(length)[None, :, None] / length
  obs = rng.uniform(-1, 1, (n, 1, obs_dim)).astype(np.float32) + 0.1 * t.astype(np.float32)
  actions = np.concatenate([np.sin(3 * t + obs[:, :, :1]), np.zeros((n, length, 9))], -1).astype(np.float32)
  obs = np.broadcast_to(obs, (n, length, obs_dim)).copy()
  buf = buffer_lib.add(buffer_lib.create(8, length, obs_dim, 10), obs, actions, np.full(n, length), np.ones(n, bool), 0)
  norm = normalizer.fit(obs.reshape(-1, obs_dim), actions.reshape(-1, 10))
  policy = make_policy(config.policy, obs_dim, 10)
  tx = train_state.make_optimizer(config.fit, config.fit.num_steps)
  params = jax.jit(policy.init)(jax.random.PRNGKey(0))  # compiled: eager initialisation takes seconds
  state = train_state.create(params, tx, norm, ema=ema)
  return config, policy, tx, state, buf


def test_ema_decay_follows_diffusion_policy():
  d = train_state.ema_decay
  assert float(d(jnp.array(1))) == 0.0
  np.testing.assert_allclose(float(d(jnp.array(2))), 1 - 2**-0.75, rtol=1e-6)
  np.testing.assert_allclose(float(d(jnp.array(10_001))), 1 - 10_001**-0.75, rtol=1e-5)
  assert float(d(jnp.array(10_000_000))) == pytest.approx(0.9999)


def test_fit_runs_in_chunks_loss_falls_and_ema_tracks():
  config, policy, tx, state, buf = _setup()
  state, history = fit.fit(policy, tx, state, buf, jax.random.PRNGKey(1), 40, config.fit, progress=False)
  assert [h["step"] for h in history] == [20, 40] and int(state.step) == 40
  assert history[-1]["loss"] < history[0]["loss"]
  diff = [float(jnp.abs(a - b).max()) for a, b in zip(jax.tree.leaves(state.params), jax.tree.leaves(state.ema_params))]
  assert max(diff) > 0  # the EMA lags the parameters


_LOAD_WITHOUT_TASKS = """
import json, sys
import numpy as np
sys.modules["soe_jax.envs"] = None  # the simulator's tasks cannot be imported
import jax
from soe_jax.train import checkpoint
loaded = checkpoint.load({path!r})
obs = np.asarray(json.loads(sys.stdin.read()), np.float32)
print(json.dumps(np.asarray(loaded.agent.act(obs, jax.random.PRNGKey(5))).tolist()))
"""


@pytest.mark.slow
def test_checkpoint_loads_without_task_registry_to_same_samples(tmp_path):
  """A checkpoint loads without the task registry and gives identical samples."""
  config, policy, tx, state, buf = _setup()  # (its fresh parameters: what is saved, not how it was fitted)
  path = str(tmp_path / "ckpt")
  checkpoint.save(path, state, config, task.spec(config))
  obs = np.asarray(buf.obs[:3, :2])
  direct = np.asarray(Agent.from_state(policy, state).act(jnp.asarray(obs), jax.random.PRNGKey(5)))
  assert direct.shape == (3, policy.n_action_steps, policy.action_dim)  # the executed actions
  script = _LOAD_WITHOUT_TASKS.format(path=path)
  proc = subprocess.run([sys.executable, "-c", script], input=json.dumps(obs.tolist()), capture_output=True, text=True,
                        cwd=ROOT, timeout=300)  # fmt: skip
  assert proc.returncode == 0, proc.stderr[-2000:]
  np.testing.assert_array_equal(np.asarray(json.loads(proc.stdout), np.float32), direct)
  loaded = checkpoint.load(path)
  chex.assert_trees_all_equal(loaded.state.params, state.params)
  assert loaded.spec == task.spec(config)


def test_older_checkpoints_load_with_the_spec_or_are_refused(tmp_path):
  """Format 2 (no spec.json) loads given the task's spec; format 1 is refused, naming why."""
  config, policy, tx, state, _ = _setup()
  path = str(tmp_path / "ckpt")
  checkpoint.save(path, state, config, task.spec(config))
  with pytest.raises(FileNotFoundError, match="config.json"):
    checkpoint.load(str(tmp_path / "missing"))
  os.remove(os.path.join(path, "spec.json"))  # as written before checkpoints carried their spec
  json.dump({"format": 2}, open(os.path.join(path, checkpoint.FORMAT_FILE), "w"))
  with pytest.raises(ValueError, match="has no spec.json.*spec="):
    checkpoint.load(path)
  assert int(checkpoint.load(path, task.spec(config)).state.step) == 0
  os.remove(os.path.join(path, checkpoint.FORMAT_FILE))  # as written before the format number existed
  with pytest.raises(ValueError, match="has format 1, this code reads formats 2 and 3.*without clipping"):
    checkpoint.load(path, task.spec(config))


_CURVE = """
import json, sys, jax
sys.path.insert(0, {root!r}); sys.path.insert(0, {tests!r})
from test_fit import _setup
from soe_jax.train import fit
config, policy, tx, state, buf = _setup(ema=False)
state, history = fit.fit(policy, tx, state, buf, jax.random.PRNGKey(1), 40, config.fit, progress=False)
print(json.dumps(dict(devices=jax.device_count(), losses=[h["loss"] for h in history])))
"""


def _loss_curve(devices: int):
  env = dict(os.environ, XLA_FLAGS=f"--xla_force_host_platform_device_count={devices}", JAX_PLATFORMS="cpu")
  code = _CURVE.format(root=ROOT, tests=os.path.dirname(os.path.abspath(__file__)))
  out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
  return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_four_devices_give_the_same_loss_curve_as_one():
  one, four = _loss_curve(1), _loss_curve(4)
  assert one["devices"] == 1 and four["devices"] == 4
  np.testing.assert_allclose(four["losses"], one["losses"], rtol=1e-4)

"""The simulator as the robot (the toy task, `tests/experiment/toy.py`): its demonstrations written as a
LeRobotDataset -> `fit` on the files -> `python -m soe_jax serve` in its own process, reached over loopback
with the token it prints -> episodes run in the simulator with the served chunks -> written as a
LeRobotDataset with the simulator's success labels -> `refit` on exactly the successful ones -> served
again: the chunk for a fixed observation and key is the new checkpoint's in-process one."""

import os
import re
import subprocess
import sys

import jax
import ml_collections
import numpy as np
import pytest
import websockets
import websockets.sync.client as ws_client

from soe_jax.data import export
from soe_jax.data.episodes import EpisodeSet
from soe_jax.envs import observations
from soe_jax.envs.registry import make_env
from soe_jax.experts import collect
from soe_jax.policies import agent as agent_lib
from soe_jax.robot import config as robot_config
from soe_jax.robot import run
from soe_jax.serve import session, wire
from soe_jax.train import checkpoint
from tests.experiment import toy

KEYS = observations.POLICY_OBS_KEYS


class Served:
  """`python -m soe_jax serve` in its own process: its port and the token it printed."""

  def __init__(self, ckpt: str):
    self.proc = subprocess.Popen([sys.executable, "-m", "soe_jax", "serve", f"--checkpoint={ckpt}", "--port=0"],
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)  # fmt: skip
    lines = []
    while not (lines and lines[-1].startswith("token: ")):
      line = self.proc.stdout.readline()
      assert line, "".join(lines)
      lines.append(line)
    self.port = int(re.search(r"ws://127\.0\.0\.1:(\d+)", "".join(lines)).group(1))
    self.token = lines[-1].split()[1]

  def connect(self, token=None):
    headers = {"Authorization": f"Api-Key {token or self.token}"}
    return ws_client.connect(f"ws://127.0.0.1:{self.port}", additional_headers=headers)

  def close(self):
    self.proc.terminate()
    self.proc.wait(timeout=30)


def _request(obs: dict, start: bool) -> dict:
  return dict({f"observation.{k}": np.asarray(obs[k], np.float32) for k in KEYS}, episode_start=start)


def test_the_simulator_as_the_robot(tmp_path):
  with toy.registered():
    env = make_env(toy.NAME)
    demos = collect.demonstrations(env, 4, 1000, progress=False)
    export.write_lerobot(str(tmp_path / "demos"), [EpisodeSet(demos, 0)], {"env_name": toy.NAME})
    config = robot_config.config("smoke")
    config.policy.head = ml_collections.ConfigDict(dict(name="mlp", kwargs=dict(hidden=(32, 32))))  # (compiles fast)
    config.dataset.update(path=str(tmp_path / "demos"), observations=tuple(f"observation.{k}" for k in KEYS),
                          gripper="identity")  # fmt: skip
    workdir = str(tmp_path / "run")
    run.fit(config, workdir, progress=False)

    server = Served(os.path.join(workdir, "rounds", "0", "ckpt"))
    try:
      with pytest.raises(websockets.InvalidStatus):  # the token is required, on loopback too
        server.connect("not-the-token")
      step, recorded = jax.jit(env.step), []
      with server.connect() as ws:
        ta = wire.unpackb(ws.recv())["action_horizon"]
        for key in jax.random.split(jax.random.key(7), 6):
          state, obs_seq, actions = env.reset(key), [], []
          while len(actions) < env.episode_length and not bool(state.metrics["success"]):
            ws.send(wire.packb(_request(state.obs, not actions)))
            for a in wire.unpackb(ws.recv())["actions"]:
              obs_seq.append({k: np.asarray(state.obs[k]) for k in KEYS})
              actions.append(a)
              state = step(state, a)
              if bool(state.metrics["success"]) or len(actions) == env.episode_length:
                break
          obs = {k: np.stack([o[k] for o in obs_seq]) for k in KEYS}
          recorded.append(dict(obs=obs, actions=np.stack(actions), success=bool(state.metrics["success"])))
    finally:
      server.close()
  successes = sum(ep["success"] for ep in recorded)
  assert 0 < successes < len(recorded)  # both labels occur
  export.write_lerobot(str(tmp_path / "recorded"), [EpisodeSet(recorded, 1)], {"env_name": toy.NAME})
  fit1 = run.refit(workdir, str(tmp_path / "recorded"), progress=False)
  assert fit1["episodes_by_source"] == {"0": 4, "1": successes}  # exactly the successful ones

  ckpt = os.path.join(workdir, "rounds", "1", "ckpt")
  server = Served(ckpt)
  try:
    with server.connect() as ws:
      ws.recv()
      obs = {k: np.asarray(v[0]) for k, v in recorded[0]["obs"].items()}
      ws.send(wire.packb(_request(obs, True)))
      served = wire.unpackb(ws.recv())["actions"]
  finally:
    server.close()
  loaded = checkpoint.load(ckpt)
  x = session.policy_input(loaded.spec, {f"observation.{k}": v for k, v in obs.items()})
  history = agent_lib.initial_history(x, loaded.policy.n_obs_steps)
  chunk = session.chunk_fn(loaded.policy)(loaded.agent, history, session.request_key(0, 0, 0))
  np.testing.assert_allclose(served, np.asarray(loaded.agent.executed(chunk))[0], atol=1e-6)
  assert served.shape == (ta, 10)

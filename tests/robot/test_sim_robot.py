"""The simulator as the robot (the toy task, `tests/experiment/toy.py`): its demonstrations written as a
LeRobotDataset -> `fit` on the files -> `python -m soe_jax serve` in its own process, reached over loopback
with the token it prints -> episodes run in the simulator with the served chunks -> written as a
LeRobotDataset with the simulator's success labels -> `refit` on exactly the successful ones -> served
again: the chunk for a fixed observation and key is the new checkpoint's in-process one.

And the exploring robot: the server explores in SOE mode and records; the robot's helper
(`soe_jax/serve/client.py`, loaded from its file) drives the episodes, one steering request is answered
through the page's API by a scripted chooser, the simulator's check labels each episode, `refit` trains on
the successes the server wrote, and `table1` reports them."""

import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
import threading
import time
import urllib.request

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
from soe_jax.serve.modes import Modes
from soe_jax.train import checkpoint
from tests.experiment import toy

KEYS = observations.POLICY_OBS_KEYS


class Served:
  """`python -m soe_jax serve` in its own process: its port, its page's and the token it printed."""

  def __init__(self, ckpt: str, *flags: str):
    self.proc = subprocess.Popen([sys.executable, "-m", "soe_jax", "serve", f"--checkpoint={ckpt}", "--port=0", *flags],
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)  # fmt: skip
    lines = []
    while not (lines and lines[-1].startswith("token: ")):
      line = self.proc.stdout.readline()
      assert line, "".join(lines)
      lines.append(line)
    self.port = int(re.search(r"ws://127\.0\.0\.1:(\d+)", "".join(lines)).group(1))
    self.page = int(re.search(r"page: http://127\.0\.0\.1:(\d+)", "".join(lines)).group(1))
    self.token = lines[-1].split()[1]
    self.instance = int(re.search(r"sampling keys seed \d+, instance (\d+)", "".join(lines)).group(1))

  def connect(self, token=None):
    headers = {"Authorization": f"Api-Key {token or self.token}"}
    return ws_client.connect(f"ws://127.0.0.1:{self.port}", additional_headers=headers)

  def close(self):
    self.proc.terminate()
    self.proc.wait(timeout=30)


def _request(obs: dict, start: bool) -> dict:
  return dict({f"observation.{k}": np.asarray(obs[k], np.float32) for k in KEYS}, episode_start=start)


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
  """Round 0 fitted on the toy task's demonstrations written as a LeRobotDataset -> its workdir."""
  root = tmp_path_factory.mktemp("sim_robot")
  with toy.registered():
    env = make_env(toy.NAME)
    demos = collect.demonstrations(env, 4, 1000, progress=False)
  export.write_lerobot(str(root / "demos"), [EpisodeSet(demos, 0)], {"env_name": toy.NAME})
  config = robot_config.config("smoke")
  config.policy.head = ml_collections.ConfigDict(dict(name="mlp", kwargs=dict(hidden=(32, 32))))  # (compiles fast)
  config.dataset.update(path=str(root / "demos"), observations=tuple(f"observation.{k}" for k in KEYS))
  config.dataset.normalize.gripper = "identity"
  workdir = str(root / "run")
  run.fit(config, workdir, progress=False)
  return workdir


@pytest.mark.slow
def test_the_simulator_as_the_robot(fitted, tmp_path):
  workdir = str(tmp_path / "run")
  shutil.copytree(fitted, workdir)
  with toy.registered():
    env = make_env(toy.NAME)
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
  key = session.request_key(0, server.instance, 0, 0)
  base = Modes(loaded.agent, loaded.spec)("base", loaded.agent, history, key)
  np.testing.assert_allclose(served, np.asarray(base)[0], atol=1e-6)  # the server's own program, in-process
  assert served.shape == (ta, 10)


def _helper():
  """The robot's helper, loaded from its file as the robot's environment would (it imports nothing of soe_jax)."""
  import soe_jax.serve

  path = os.path.join(os.path.dirname(soe_jax.serve.__file__), "client.py")
  spec = importlib.util.spec_from_file_location("robot_helper", path)
  module = importlib.util.module_from_spec(spec)
  spec.loader.exec_module(module)
  return module


class Policy:
  """openpi-client's `WebsocketClientPolicy` in miniature (the openpi-client test runs the real one)."""

  def __init__(self, ws):
    self.ws = ws
    self.metadata = wire.unpackb(ws.recv())

  def get_server_metadata(self):
    return self.metadata

  def infer(self, obs):
    self.ws.send(wire.packb(obs))
    reply = self.ws.recv()
    if isinstance(reply, str):
      raise RuntimeError(f"Error in inference server:\n{reply}")
    return wire.unpackb(reply)


def _page(port: int, token: str, path: str, body=None):
  req = urllib.request.Request(f"http://127.0.0.1:{port}{path}", None if body is None else json.dumps(body).encode(),
                               {"Authorization": f"Api-Key {token}", "Content-Type": "application/json"})  # fmt: skip
  with urllib.request.urlopen(req, timeout=10) as r:
    return json.load(r)


def _choose_first_proposal(server: Served, chosen: list) -> None:
  """A scripted person: waits for a steering request on the page and picks its first proposal."""
  deadline = time.monotonic() + 60
  while time.monotonic() < deadline:
    for c in _page(server.page, server.token, "/api/state")["connections"]:
      if (c["steering"] or {}).get("waiting"):
        _page(
          server.page,
          server.token,
          "/api/choose",
          dict(connection=c["name"], request=c["steering"]["request"], index=0),
        )
        chosen.append(c["steering"]["request"])
        return
    time.sleep(0.05)


def test_the_exploring_robot_labels_and_refits(fitted, tmp_path):
  workdir = str(tmp_path / "run")
  shutil.copytree(fitted, workdir)
  assert len(json.load(open(os.path.join(workdir, "rounds", "0", "fit.json")))["snr_db"]) > 0  # for steering
  record = str(tmp_path / "recorded")
  server = Served(os.path.join(workdir, "rounds", "0", "ckpt"), f"--record={record}", "--mode=soe",
                  "--steer_timeout=60")  # fmt: skip
  helper, labels, chosen = _helper(), [], []
  try:
    with toy.registered():
      env = make_env(toy.NAME)
      step = jax.jit(env.step)
      with server.connect() as ws:
        runner = helper.EpisodeRunner(policy=Policy(ws))
        for i, key in enumerate(jax.random.split(jax.random.key(11), 6)):
          sim = {"state": env.reset(key)}
          observe = lambda: {f"observation.{k}": np.asarray(sim["state"].obs[k], np.float32) for k in KEYS}
          act = lambda a: sim.update(state=step(sim["state"], a))
          done = lambda _: bool(sim["state"].metrics["success"])
          label = lambda: labels.append("success" if done(None) else "failure") or labels[-1]
          mode = (lambda d: "steer" if d == 0 else "soe") if i == 0 else "soe"
          chooser = threading.Thread(target=_choose_first_proposal, args=(server, chosen)) if i == 0 else None
          if chooser:
            chooser.start()
          out = runner.run_episode(observe, act, mode, env.episode_length, done, label, start_state=i // 2)
          if chooser:
            chooser.join()
          assert out["written"] and out["label"] == labels[-1]
        assert runner.last_steering["chosen"] == 0 and chosen == ["0-0"]
  finally:
    server.close()
  successes = labels.count("success")
  assert 0 < successes < len(labels)  # both labels occur
  fit1 = run.refit(workdir, os.path.join(record, "lerobot"), progress=False)
  assert fit1["episodes_by_source"] == {"0": 4, "1": successes}  # exactly the successful ones

  out = subprocess.run([sys.executable, "-m", "soe_jax", "table1", os.path.join(record, "lerobot"), "--k=2",
                        f"--spec={workdir}", f"--out={tmp_path / 'table1.json'}"], capture_output=True, text=True)  # fmt: skip
  assert out.returncode == 0, out.stderr
  table = json.load(open(tmp_path / "table1.json"))["explore"]["modes"]
  assert set(table) == {"steer", "soe"} and table["steer"]["episodes"] == 1 and table["soe"]["episodes"] == 5
  assert table["soe"]["successes"] + table["steer"]["successes"] == successes
  assert "| soe | 5 |" in out.stdout

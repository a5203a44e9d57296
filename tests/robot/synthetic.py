"""A synthetic robot end to end, in a process where importing `soe_jax.envs` raises: 7-d proprioception
(end-effector position and xyzw quaternion), 10-d absolute actions with the gripper in metres, no object
vector, optionally one 96 x 128 camera. Demonstrations written as a LeRobotDataset -> `fit` -> served over
loopback with the token -> recorded episodes with success labels written as a LeRobotDataset -> `refit`
-> served again. Prints one JSON line of what the test checks.

  python -m tests.robot.synthetic WORKDIR [--image]
"""

from __future__ import annotations

import importlib.abc
import json
import os
import sys


class _NoSimulator(importlib.abc.MetaPathFinder):
  def find_spec(self, name, path=None, target=None):
    if name == "soe_jax.envs" or name.startswith("soe_jax.envs."):
      raise ImportError(f"{name}: no simulator in this process")
    return None


# A 7-d axis-angle arm: position, rotation vector, gripper (its action parts, `dataset.actions`).
AXIS_ANGLE_ARM = (("position", 3), ("axis_angle", 3), ("gripper", 1))


def axis_angle_episodes(rng, n: int = 4, length: int = 24) -> list[dict]:
  """The hand turns about x through angles near pi, either way (the rotation vector's x near +-3.1: a
  jump of 2 pi between episodes that rotation-6d does not have), drifting; actions as observations."""
  import numpy as np

  out = []
  for _ in range(n):
    pos = rng.uniform(-0.2, 0.2, 3) + np.linspace(0, 0.1, length)[:, None]
    angle = np.linspace(2.9, 3.1, length) + rng.normal(0, 0.01, length)
    axis = np.stack([np.ones(length), rng.normal(0, 0.05, length), rng.normal(0, 0.05, length)], -1)
    rotvec = np.sign(rng.uniform(-1, 1)) * angle[:, None] * axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    grip = np.linspace(0.08, 0.0, length)[:, None]
    actions = np.concatenate([pos, rotvec, grip], -1).astype(np.float32)
    out.append({"obs": {"observation.state": actions.copy()}, "actions": actions})
  return out


def episodes(rng, n: int, length: int, image: bool, success=None) -> list[dict]:
  """Random smooth episodes: the hand drifts towards a goal; the action commands the next pose."""
  import numpy as np

  out = []
  for i in range(n):
    goal = rng.uniform([-0.2, -0.2, 0.1], [0.2, 0.2, 0.4])
    pos = np.zeros((length + 1, 3))
    pos[0] = rng.uniform([-0.1, -0.1, 0.2], [0.1, 0.1, 0.3])
    for t in range(length):
      pos[t + 1] = pos[t] + 0.1 * (goal - pos[t])
    quat = np.tile([0.0, 1.0, 0.0, 0.0], (length, 1)) + rng.normal(0, 0.01, (length, 4))  # xyzw, hand down
    quat /= np.linalg.norm(quat, axis=-1, keepdims=True)
    rot6d = np.tile([1.0, 0.0, 0.0, 0.0, -1.0, 0.0], (length, 1))  # the rotation's first two rows
    grip = np.linspace(0.08, 0.0, length)[:, None]  # metres
    obs = {"observation.state": np.concatenate([pos[:-1], quat], -1).astype(np.float32)}
    if image:
      frames = np.zeros((length, 96, 128, 3), np.uint8)
      frames[..., 0] = (np.arange(length)[:, None, None] * 8) % 255
      obs["observation.images.wrist"] = frames
    ep = {"obs": obs, "actions": np.concatenate([pos[1:], rot6d, grip], -1).astype(np.float32)}
    if success is not None:
      ep["success"] = bool(success[i])
    out.append(ep)
  return out


def main(argv: list[str]) -> None:
  sys.meta_path.insert(0, _NoSimulator())
  import jax
  import ml_collections
  import numpy as np
  import websockets.sync.client as ws_client

  from soe_jax.data import lerobot
  from soe_jax.policies import agent as agent_lib
  from soe_jax.robot import config as robot_config
  from soe_jax.robot import run
  from soe_jax.serve import session, wire
  from soe_jax.serve.modes import Modes
  from soe_jax.serve.server import PolicyServer
  from soe_jax.train import checkpoint

  workdir, image = argv[1], "--image" in argv
  rng = np.random.default_rng(0)
  demos_dir, recorded_dir = os.path.join(workdir, "demos"), os.path.join(workdir, "recorded")
  lerobot.write_dataset(demos_dir, episodes(rng, 4, 24, image), fps=10)
  config = robot_config.config("smoke,image" if image else "smoke")
  # A small MLP head: the path's logic is the same for every head, and it compiles in a fraction of the time.
  config.policy.head = ml_collections.ConfigDict(dict(name="mlp", kwargs=dict(hidden=(32, 32))))
  config.dataset.path = demos_dir
  config.dataset.poses = ({"position": ["observation.state", 0], "orientation": ["observation.state", 3]},)
  run_dir = os.path.join(workdir, "run")
  fit0 = run.fit(config, run_dir, progress=False)

  token = "t0ken"
  labels = [True, False, True]

  def serve_and_record(r: int, record: bool) -> tuple[list, np.ndarray, np.ndarray]:
    """Serve round r; drive it with observations of fresh episodes; return the recorded episodes, one
    reply and the in-process chunk for the same observation and key."""
    loaded = checkpoint.load(os.path.join(run_dir, "rounds", str(r), "ckpt"))
    server = PolicyServer(loaded.agent, loaded.spec, token, port=0, instance=0).start()
    try:
      rec, first = [], None
      with ws_client.connect(
        f"ws://127.0.0.1:{server.port}", additional_headers={"Authorization": f"Api-Key {token}"}
      ) as ws:
        meta = wire.unpackb(ws.recv())
        for ep in episodes(rng, 3 if record else 1, 16, image, labels):
          actions = []
          for t in range(0, 16, meta["action_horizon"]):
            obs = {k: v[t] for k, v in ep["obs"].items()}
            ws.send(wire.packb(dict(obs, episode_start=t == 0, timestamp=t / 10)))
            reply = wire.unpackb(ws.recv())
            first = (obs, reply["actions"]) if first is None else first
            actions.append(reply["actions"])
          rec.append(dict(ep, actions=np.concatenate(actions)[:16].astype(np.float32)))
    finally:
      server.shutdown()
    obs, replied = first
    x = session.policy_input(loaded.spec, obs)
    history = agent_lib.initial_history(x, loaded.policy.n_obs_steps)
    agent = loaded.agent  # the base path's program, as the server compiles it (otherwise XLA fuses differently: ~1e-5)
    inproc = np.asarray(Modes(agent, loaded.spec)("base", agent, history, session.request_key(0, 0, 0, 0)))[0]
    return rec, replied, inproc

  recorded, replied0, inproc0 = serve_and_record(0, True)
  lerobot.write_dataset(recorded_dir, recorded, fps=10)
  fit1 = run.refit(run_dir, recorded_dir, progress=False)
  _, replied1, inproc1 = serve_and_record(1, False)
  loaded = checkpoint.load(os.path.join(run_dir, "rounds", "1", "ckpt"))
  norm = loaded.state.normalizer
  print(json.dumps(dict(
    fit0=fit0["episodes_by_source"], fit1=fit1["episodes_by_source"], labels=labels,
    served0=float(np.abs(replied0 - inproc0).max()), served1=float(np.abs(replied1 - inproc1).max()),
    control_hz=loaded.spec.control_hz, gripper_scale=float(norm.act_scale[9]),
    envs_imported=any(m.startswith("soe_jax.envs") for m in sys.modules), devices=str(jax.devices()[0].platform),
  )))  # fmt: skip


if __name__ == "__main__":
  main(sys.argv)

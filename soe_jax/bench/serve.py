"""The policy server's latency per chunk: a policy of the config's size (random weights; the time does
not depend on them) served over loopback, p50 / p95 over `requests` requests after `warmup`, against
the same requests answered in-process (`serve.session.Session.infer`: the observation checked, the
history pushed, the chunk sampled and checked); the difference is the wire's overhead (msgpack both
ways, the websocket, the server's thread). Compiling is timed apart."""

from __future__ import annotations

import time

import jax
import ml_collections
import numpy as np
import websockets.sync.client as ws_client

from soe_jax.experiment import task
from soe_jax.policies import normalizer as normalizer_lib
from soe_jax.policies.agent import Agent
from soe_jax.serve import session as session_lib
from soe_jax.serve import wire
from soe_jax.serve.server import PolicyServer

TOKEN = "bench"


def _observations(spec, n: int, rng, camera_size: tuple[int, int] | None = None) -> list[dict]:
  """`camera_size`: (height, width) each camera sends (the server resizes it to the policy's with
  padding); None: the policy's own size."""
  out = []
  for i in range(n):
    obs = {}
    for k, v in spec.observations.items():
      if v.get("image"):
        shape = (*camera_size, v["shape"][-1]) if camera_size else v["shape"]
        obs[k] = rng.integers(0, 256, shape, np.uint8)
      else:
        obs[k] = rng.normal(0, 0.1, v["shape"]).astype(np.float32)
    out.append(dict(obs, episode_start=i % 50 == 0, timestamp=0.1 * i))
  return out


def _ms(times) -> dict:
  t = 1000 * np.asarray(times)
  return dict(p50=round(float(np.percentile(t, 50)), 2), p95=round(float(np.percentile(t, 95)), 2))


def serve(
  config: ml_collections.ConfigDict, requests: int = 200, warmup: int = 20, camera_size: tuple[int, int] | None = None
) -> dict:
  """`camera_size`: (height, width) of the images each request carries, as a robot's cameras send them
  (the server resizes them to the policy's size, `serve.session`, and the time includes it); None: the
  policy's own size."""
  spec, policy = task.spec(config), task.policy(config)
  rng = np.random.default_rng(0)
  # A normaliser over the spec's action box, so the sampled chunks are inside it (the server checks).
  obs_frames = rng.normal(0, 0.1, (64, policy.obs_dim))
  actions = rng.uniform(-0.1, 0.1, (64, policy.action_dim))
  norm = normalizer_lib.fit(obs_frames, actions, action_box=spec.action_bounds(), ranged=spec.ranged_action_dims())
  agent = Agent(policy, policy.init(jax.random.key(0)), norm)
  observations = _observations(spec, warmup + requests, rng, camera_size)

  t = time.perf_counter()
  session_lib.warm_up(agent, spec)
  compile_s = time.perf_counter() - t
  local = session_lib.Session(agent, spec)
  inproc = []
  for i, obs in enumerate(observations):
    t = time.perf_counter()
    local.infer(obs)
    if i >= warmup:
      inproc.append(time.perf_counter() - t)

  server = PolicyServer(agent, spec, TOKEN, port=0).start()
  wire_times, infer_ms = [], []
  try:
    headers = {"Authorization": f"Api-Key {TOKEN}"}
    with ws_client.connect(f"ws://127.0.0.1:{server.port}", additional_headers=headers, max_size=None) as ws:
      ws.recv()
      for i, obs in enumerate(observations):
        frame = wire.packb(obs)
        t = time.perf_counter()
        ws.send(frame)
        reply = wire.unpackb(ws.recv())
        if i >= warmup:
          wire_times.append(time.perf_counter() - t)
          infer_ms.append(reply["server_timing"]["infer_ms"] / 1000)
  finally:
    server.shutdown()
  wire_ms, local_ms = _ms(wire_times), _ms(inproc)
  return dict(
    bench="serve",
    task=config.env.task,
    obs_encoder=config.policy.encoder.name,
    down_dims=list(config.policy.head.kwargs.get("down_dims", [])),
    images=[list(spec.observations[k]["shape"]) for k in spec.image_keys],
    sent=[list(observations[0][k].shape) for k in spec.image_keys],
    request_bytes=len(wire.packb(observations[0])),
    requests=requests,
    warmup=warmup,
    compile_s=round(compile_s, 2),
    in_process_ms=local_ms,
    server_infer_ms=_ms(infer_ms),
    round_trip_ms=wire_ms,
    wire_overhead_ms=round(wire_ms["p50"] - local_ms["p50"], 2),
    devices=str(jax.devices()[0].platform),
  )

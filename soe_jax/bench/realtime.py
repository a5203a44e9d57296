"""Real-time chunks against the blocking loop, with the simulator as a robot at its own rate.

The robot (`PacedRobot`) advances one control step per wall-clock tick at `hz`, whether or not a new
command has come (it holds the last one), from its first command on. A fitted checkpoint's policy is
served in-process over loopback (`serve.server.PolicyServer`, its spec's rate set to `hz`) and driven by
the robot-side helper (`serve/client.py`) through a websocket client that waits `delay_ms` before each
request leaves and after each reply arrives (the link's delay each way). Each loop (`blocking`, or
`realtime` with `client.RealTime`'s settings) runs the same `states` start states (paired: keys split
from `seed`), each episode the task's length in robot ticks or until it succeeds, and reports per rate
and loop: idle time per second (ticks at which the robot held its command for want of a new one, over
all ticks), the actions dropped (due before their reply arrived), commands replaced before the robot
took them, requests, success per state, and the machine's load (`os.getloadavg`) before and after.
The wait for an episode's first chunk, before the robot has a command to hold, is not counted.
"""

from __future__ import annotations

import dataclasses
import os
import threading
import time

import jax
import numpy as np
import websockets.sync.client as ws_client

from soe_jax.analysis.tables import markdown, pct
from soe_jax.experiment import task
from soe_jax.serve import client, wire
from soe_jax.serve.server import PolicyServer
from soe_jax.train import checkpoint

TOKEN = "bench"
LOOPS = ("blocking", "realtime")


class DelayedPolicy:
  """openpi-client's `WebsocketClientPolicy` in miniature over `ws`, with `delay_s` of the link's delay
  each way: before a request leaves and after its reply arrives."""

  def __init__(self, ws, delay_s: float = 0.0):
    self.ws, self.delay_s = ws, float(delay_s)
    self.metadata = wire.unpackb(ws.recv())

  def get_server_metadata(self) -> dict:
    return self.metadata

  def infer(self, obs: dict) -> dict:
    time.sleep(self.delay_s)
    self.ws.send(wire.packb(obs))
    reply = self.ws.recv()
    time.sleep(self.delay_s)
    if isinstance(reply, str):
      raise RuntimeError(f"Error in inference server:\n{reply}")
    return wire.unpackb(reply)


class PacedRobot:
  """The simulator as a robot with its own clock: from the first command on, one control step per tick
  at `hz` with the latest command, new or held, until it succeeds or has stepped `length` ticks (`over`).
  A tick falls half a period after the first command's time, so a command sent at a client's tick
  reaches the next robot tick despite jitter."""

  def __init__(self, step, state, keys, hz: float, length: int):
    self.step, self.state, self.keys, self.dt, self.length = step, state, tuple(keys), 1.0 / float(hz), int(length)
    self.command, self.sent, self.stepped = None, 0, 0  # the latest command, its number, the last stepped
    self.ticks = self.idle = self.replaced = 0
    self.success = bool(state.metrics["success"])
    self.cond, self.running, self.thread = threading.Condition(), True, None

  def observe(self) -> dict:
    with self.cond:
      return {k: np.asarray(self.state.obs[k]) for k in self.keys}

  def act(self, action, wait: bool) -> None:
    """Send `action`; `wait`: return once a tick has stepped with it (the blocking loop's `act`)."""
    with self.cond:
      if self.command is not None and self.stepped < self.sent:
        self.replaced += 1
      self.command, self.sent = np.asarray(action), self.sent + 1
      mine = self.sent
      if self.thread is None:
        self.thread = threading.Thread(target=self._run, args=(time.monotonic() + self.dt / 2,), daemon=True)
        self.thread.start()
      if wait:
        self.cond.wait_for(lambda: self.stepped >= mine or not self.running)

  def _run(self, t0: float) -> None:
    while True:
      time.sleep(max(0.0, t0 + self.ticks * self.dt - time.monotonic()))
      with self.cond:
        if not self.running:
          return
        command, number, state = self.command, self.sent, self.state
      state = self.step(state, command)
      success = bool(state.metrics["success"])
      with self.cond:
        self.idle += number == self.stepped  # no command since the last tick: held
        self.state, self.stepped, self.ticks = state, number, self.ticks + 1
        self.success = self.success or success
        self.running = self.running and not (self.success or self.ticks >= self.length)
        self.cond.notify_all()

  @property
  def over(self) -> bool:
    with self.cond:
      return not self.running

  def stop(self) -> None:
    with self.cond:
      self.running = False
      self.cond.notify_all()
    if self.thread is not None:
      self.thread.join()


def _episode(runner: client.EpisodeRunner, env, step, key, spec, hz: float, realtime: bool) -> dict:
  """One episode from start state `key`, the robot at `hz` -> its success, ticks, idle ticks, replaced
  commands, dropped actions and requests."""
  robot = PacedRobot(step, env.reset(key), spec.observations, hz, env.episode_length)
  try:
    runner.run_episode(robot.observe, lambda a: robot.act(a, wait=not realtime), max_steps=10**9,
                       done=lambda _: robot.over, label=lambda: "discard")  # fmt: skip
  finally:
    robot.stop()
  return dict(success=robot.success, ticks=robot.ticks, idle=robot.idle, replaced=robot.replaced,
              dropped=runner.stats["dropped"], requests=runner.stats["requests"])  # fmt: skip


def run(ckpt: str, rates: tuple[float, ...] = (10.0, 30.0), delay_ms: float = 50.0, states: int = 50, seed: int = 0,
        loops: tuple[str, ...] = LOOPS, realtime: client.RealTime | None = None, mode: str = "base",
        progress=None) -> dict:  # fmt: skip
  """Each rate x loop over the same `states` start states -> the record's `realtime` part (`realtime`:
  the real-time loop's settings, default `client.RealTime()`; `progress`: called with a line per episode)."""
  realtime = realtime if realtime is not None else client.RealTime()
  if bad := [x for x in loops if x not in LOOPS]:
    raise ValueError(f"unknown loop {bad[0]!r}; known: {', '.join(LOOPS)}")
  loaded = checkpoint.load(ckpt)
  env = task.env(loaded.config)
  step = jax.jit(env.step)
  keys = jax.random.split(jax.random.key(seed), states)
  jax.block_until_ready(step(env.reset(keys[0]), np.zeros(loaded.spec.action_dim, np.float32)))  # compiled first
  load_before = os.getloadavg()
  results = []
  for hz in rates:
    spec = dataclasses.replace(loaded.spec, control_hz=float(hz))
    server = PolicyServer(loaded.agent, spec, TOKEN, port=0, default_mode=mode).start()
    try:
      for loop in loops:
        headers = {"Authorization": f"Api-Key {TOKEN}"}
        with ws_client.connect(f"ws://127.0.0.1:{server.port}", additional_headers=headers, max_size=None) as ws:
          runner = client.EpisodeRunner(policy=DelayedPolicy(ws, delay_ms / 1000),
                                        realtime=realtime if loop == "realtime" else None)  # fmt: skip
          episodes = []
          for i, key in enumerate(keys):
            episodes.append(_episode(runner, env, step, key, spec, hz, loop == "realtime"))
            if progress:
              progress(f"{hz:g} Hz {loop}: state {i + 1}/{states}, success {episodes[-1]['success']}")
        results.append(_summary(hz, loop, episodes))
    finally:
      server.shutdown()
  return dict(
    bench="realtime",
    checkpoint=os.path.abspath(ckpt),
    task=loaded.config.env.task,
    action_horizon=loaded.policy.n_action_steps,
    episode_length=env.episode_length,
    states=states,
    seed=seed,
    delay_ms_each_way=delay_ms,
    mode=mode,
    realtime=realtime.settings(),
    load_before=[round(x, 2) for x in load_before],
    load_after=[round(x, 2) for x in os.getloadavg()],
    cpus=os.cpu_count(),
    devices=str(jax.devices()[0].platform),
    results=results,
  )


def _summary(hz: float, loop: str, episodes: list[dict]) -> dict:
  total = lambda k: int(sum(e[k] for e in episodes))
  ticks = total("ticks")
  return dict(
    hz=hz,
    loop=loop,
    idle_s_per_s=round(total("idle") / max(ticks, 1), 4),
    dropped=total("dropped"),
    dropped_per_episode=round(total("dropped") / len(episodes), 2),
    replaced=total("replaced"),
    requests=total("requests"),
    ticks=ticks,
    success_rate=round(float(np.mean([e["success"] for e in episodes])), 4),
    success=[int(e["success"]) for e in episodes],
  )


def table(records: list[tuple[str, dict]]) -> str:
  """`bench realtime` records: per rate and loop, idle time per second, dropped and replaced actions,
  requests and success on the paired states, with the delay and the machine's load."""
  rows = []
  for name, r in records:
    s = r["realtime"]
    for x in s["results"]:
      rows.append([name, f"{x['hz']:g} Hz", x["loop"], f"{s['delay_ms_each_way']:g} ms", f"{x['idle_s_per_s']:.3f} s",
                   f"{x['dropped_per_episode']:.1f}", x["replaced"], x["requests"],
                   f"{pct(x['success_rate'])} of {len(x['success'])}",
                   " / ".join(f"{v:.2f}" for v in s["load_before"][:1] + s["load_after"][:1]), r.get("machine", "-")])  # fmt: skip
  header = ["record", "rate", "loop", "delay each way", "idle per second", "dropped per episode", "replaced",
            "requests", "success", "load before / after", "machine"]  # fmt: skip
  return markdown(header, rows)

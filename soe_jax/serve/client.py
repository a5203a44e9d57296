"""The robot's side of `python -m soe_jax serve`: one file that imports nothing of soe_jax, for the
robot's own environment (openpi-client, numpy < 2). Copy it beside the robot's code.

    from client import EpisodeRunner, RealTime, keyboard_label
    runner = EpisodeRunner("127.0.0.1", 8000, api_key=TOKEN)     # the token `serve` printed
    result = runner.run_episode(observe, act, mode="soe", max_steps=600, done=None,
                                label=keyboard_label, start_state=3)

`observe()` returns the robot's observation dict (the keys of the server's spec, raw units, images
uint8 H x W x 3 of any size: the server resizes them to the metadata's `image_size`, keeping the
aspect ratio and padding with black). Every camera in it (`observation.images.*`, uint8 H x W x 3) is
sent, those the policy does not read too: the server's page shows them, and a recording keeps those of
the dataset the policy was fitted on (the metadata's `recorded_cameras`). The episode ends when
`done(observation)` says so or after `max_steps`; then `label()` returns "success", "failure" or
"discard" (`keyboard_label`: j / k / d, SIME's keys), or None to label it on the server's page
instead. `start_state` names the attempt group (tries from one start state) for Pass@k and
`refit.select=first_success`. `mode` may be a function of the decision's index (e.g. steer every
fourth decision, the base path between).

Two loops (`EpisodeRunner(..., realtime=None | RealTime(...))`):
- blocking (the default): ask for a chunk, execute it, ask again. `act(action)` sends one absolute
  action (A,) to the robot and returns when it is due to have run (the server's `control_hz`); the
  robot idles while each request is answered. Each request carries the observations taken after each
  executed action, so the server's history holds consecutive steps and its recorder every step.
- real-time chunks (`RealTime`): one step per control tick, timed by the replies' `timestamps`, and
  the next chunk asked for while the current one executes, once at most `threshold` of its actions
  remain. `act(action)` must return at once (send the command, do not wait for it); at each tick the
  runner observes, then sends the action due then, or the last one again when none is (the robot holds
  its command: an idle tick). Actions whose tick has passed when their reply arrives are dropped
  (Diffusion Policy's `action_exec_latency`); where chunks overlap, `aggregate` picks the action:
  `latest` (the newest chunk's) or `ensemble` (ACT's temporal ensemble). Each request carries, with
  the observations taken at the ticks since the last one, the actions executed at those ticks
  (`executed`) and the request whose chunk each came from (`executed_from`), which the server records.
"""

from __future__ import annotations

import concurrent.futures
import time

import numpy as np

KEYS = {"j": "success", "k": "failure", "d": "discard"}
AGGREGATES = ("latest", "ensemble")


def keyboard_label(prompt: str = "label the episode: [j] success, [k] failure, [d] discard: ") -> str:
  while True:
    answer = input(prompt).strip().lower()
    if answer in KEYS:
      return KEYS[answer]
    print(f"{answer!r}: press j, k or d")


def _is_camera(observations: list, key) -> bool:
  """Whether `key` is a camera (`observation.images.*`) every one of `observations` has, uint8 H x W x 3
  of one size."""
  if not str(key).startswith("observation.images.") or any(key not in o for o in observations):
    return False
  values = [np.asarray(o[key]) for o in observations]
  return all(v.dtype == np.uint8 and v.ndim == 3 and v.shape[-1] == 3 and v.shape == values[0].shape for v in values)


class RealTime:
  """Real-time chunks' settings: ask for the next chunk once at most `threshold` actions of those
  scheduled remain (None: half the chunk, `action_horizon // 2`); where chunks overlap, execute the
  newest chunk's action (`aggregate="latest"`) or ACT's temporal ensemble (`"ensemble"`: the average
  weighted by exp(-ensemble_k * i), i = 0 for the oldest chunk; ACT's and SIME's k = 0.01).
  (A plain class, not a dataclass: this file is loaded from its path too, outside `sys.modules`.)"""

  def __init__(self, threshold: int | None = None, aggregate: str = "latest", ensemble_k: float = 0.01):
    if aggregate not in AGGREGATES:
      raise ValueError(f"unknown aggregate {aggregate!r}; known: {', '.join(AGGREGATES)}")
    if threshold is not None and (isinstance(threshold, bool) or not isinstance(threshold, int) or threshold < 0):
      raise ValueError(f"threshold must be a whole number of actions >= 0 (or None), got {threshold!r}")
    if not np.isfinite(ensemble_k) or ensemble_k < 0:
      raise ValueError(f"ensemble_k must be a number >= 0, got {ensemble_k!r}")
    self.threshold, self.aggregate, self.ensemble_k = threshold, aggregate, float(ensemble_k)

  def settings(self) -> dict:
    """The settings as keyword arguments: `RealTime(**rt.settings())` is `rt` again."""
    return dict(threshold=self.threshold, aggregate=self.aggregate, ensemble_k=self.ensemble_k)

  def __repr__(self) -> str:
    return "RealTime(" + ", ".join(f"{k}={v!r}" for k, v in self.settings().items()) + ")"


class Schedule:
  """The actions due at each control tick (tick i at `t0 + i * dt`) from the chunks received so far:
  a chunk's actions go to the ticks of their timestamps, those already passed are dropped, and where
  chunks overlap `aggregate` decides (`RealTime`)."""

  def __init__(self, t0: float, dt: float, aggregate: str = "latest", ensemble_k: float = 0.01):
    if aggregate not in AGGREGATES:
      raise ValueError(f"unknown aggregate {aggregate!r}; known: {', '.join(AGGREGATES)}")
    self.t0, self.dt, self.aggregate, self.ensemble_k = float(t0), float(dt), aggregate, float(ensemble_k)
    self.due: dict[int, list[tuple[int, np.ndarray]]] = {}  # tick -> [(request, action)], oldest chunk first
    self.dropped = 0  # actions whose tick had passed when their chunk arrived

  def tick_of(self, stamp: float) -> int:
    return int(round((float(stamp) - self.t0) / self.dt))

  def add(self, actions, timestamps, request: int, now: int) -> int:
    """Chunk `actions` (T, A) of request `request`, due at `timestamps` (T,), arriving at tick `now`
    -> how many were dropped: those due before `now`. When all were, the last is due now (Diffusion
    Policy's rule), so a late chunk still moves the robot."""
    actions, ticks = np.asarray(actions), [self.tick_of(t) for t in np.asarray(timestamps)]
    if len(actions) != len(ticks):
      raise ValueError(f"{len(actions)} actions with {len(ticks)} timestamps")
    kept = [(t, a) for t, a in zip(ticks, actions) if t >= now]
    if not kept and len(actions):
      kept = [(now, actions[-1])]
    dropped = len(actions) - len(kept)
    for t, a in kept:
      entries = self.due.setdefault(t, [])
      if self.aggregate == "latest":
        entries.clear()
      entries.append((int(request), np.asarray(a)))
    self.dropped += dropped
    return dropped

  def remaining(self, now: int) -> int:
    """Ticks from `now` on with an action due."""
    return sum(1 for t in self.due if t >= now)

  def pop(self, now: int) -> tuple[np.ndarray, int] | None:
    """The action due at tick `now` and the newest request it comes from (None: none is due), forgetting
    this tick and those before it."""
    for t in [t for t in self.due if t < now]:
      del self.due[t]
    entries = self.due.pop(now, None)
    if not entries:
      return None
    if len(entries) == 1:
      return entries[0][1], entries[0][0]
    w = np.exp(-self.ensemble_k * np.arange(len(entries)))
    action = np.tensordot(w / w.sum(), np.stack([a for _, a in entries]), axes=1).astype(entries[-1][1].dtype)
    return action, entries[-1][0]


class EpisodeRunner:
  """Runs episodes against a soe_jax policy server (openpi-client's `WebsocketClientPolicy`, or any
  object with its `infer` and `get_server_metadata`), in the blocking loop or, given `realtime`
  (`RealTime`), with real-time chunks."""

  def __init__(self, host: str = "127.0.0.1", port: int = 8000, api_key: str | None = None, policy=None,
               realtime: RealTime | None = None):  # fmt: skip
    if policy is None:
      from openpi_client import websocket_client_policy

      policy = websocket_client_policy.WebsocketClientPolicy(host, port, api_key=api_key)
    if realtime is not None and not isinstance(realtime, RealTime):
      raise ValueError(f"realtime is None (the blocking loop) or a RealTime, got {type(realtime).__name__}")
    self.policy, self.realtime = policy, realtime
    self.metadata = policy.get_server_metadata()
    self.keys = list(self.metadata["spec"]["observations"])
    self.last_steering = None  # the last steer reply's proposals, choice and whether it timed out
    self.stats: dict = {}  # the last episode's: ticks, idle ticks, dropped actions, requests

  def _sent_keys(self, observations: list) -> list:
    """The spec's keys, then every other camera all of `observations` have."""
    return self.keys + [k for k in observations[0] if k not in self.keys and _is_camera(observations, k)]

  def _stack(self, observations: list) -> dict:
    return {k: np.stack([np.asarray(o[k]) for o in observations]) for k in self._sent_keys(observations)}

  def _infer(self, request: dict) -> dict:
    reply = self.policy.infer(request)
    if "steering" in reply:
      self.last_steering = reply["steering"]
    return reply

  def run_episode(self, observe, act, mode="base", max_steps: int = 1000, done=None, label=None,
                  start_state: int | None = None) -> dict:  # fmt: skip
    """One episode -> the server's `recorded` answer (whether it was written, and as which episode)."""
    mode_of = mode if callable(mode) else (lambda decision: mode)
    first = observe()
    request = {k: np.asarray(first[k]) for k in self._sent_keys([first])}
    request.update(episode_start=True, timestamp=time.time(), mode=mode_of(0))
    loop = self._blocking if self.realtime is None else self._real_time
    end = loop(request, observe, act, mode_of, max_steps, done)
    end.update(episode_end=True, timestamp=time.time())
    answer = label() if label is not None else None
    if answer is not None:
      end["label"] = answer
    if start_state is not None:
      end["start_state"] = int(start_state)
    return self.policy.infer(end)["recorded"]

  def _blocking(self, request: dict, observe, act, mode_of, max_steps: int, done) -> dict:
    """Ask, execute the chunk, ask again -> the end's request (the observations since the last)."""
    steps, decision, since, finished = 0, 0, [], False
    while not finished:
      reply = self._infer(request)
      since = []
      for action in np.asarray(reply["actions"]):
        act(action)
        obs = observe()
        since.append(obs)
        steps += 1
        if steps >= max_steps or (done is not None and done(obs)):
          finished = True
          break
      if not finished:
        decision += 1
        request = dict(self._stack(since), timestamp=time.time(), mode=mode_of(decision))
    self.stats = dict(ticks=steps, idle=0, dropped=0, requests=decision + 1)
    return self._stack(since)

  def _real_time(self, request: dict, observe, act, mode_of, max_steps: int, done) -> dict:
    """One step per control tick, the next chunk asked for while this one executes -> the end's
    request (the observations since the last, the actions executed at them and their requests). The
    first chunk is waited for (the robot has no command to hold yet) and starts at the first tick."""
    rt, dt = self.realtime, 1.0 / float(self.metadata["control_hz"])
    threshold = rt.threshold if rt.threshold is not None else int(self.metadata["action_horizon"]) // 2
    reply = self._infer(request)
    t0 = time.time()
    schedule = Schedule(t0, dt, rt.aggregate, rt.ensemble_k)
    schedule.add(reply["actions"], t0 + dt * np.arange(len(reply["actions"])), 0, 0)
    since, executed, sources, last = [], [], [], None
    tick, steps, idle, requests, pending = 0, 0, 0, 1, None
    with concurrent.futures.ThreadPoolExecutor(1) as pool:  # the one request in flight
      while True:
        if tick:
          time.sleep(max(0.0, t0 + tick * dt - time.time()))
          obs = observe()
          since.append(obs)
          steps += 1
          if steps >= max_steps or (done is not None and done(obs)):
            break
        if pending is not None and pending[1].done():
          reply = pending[1].result()
          schedule.add(reply["actions"], reply["timestamps"], pending[0], tick)
          pending = None
        if tick and pending is None and schedule.remaining(tick) <= threshold:
          ask = dict(self._stack(since), executed=np.stack(executed), executed_from=np.asarray(sources, np.int64),
                     timestamp=t0 + tick * dt, mode=mode_of(requests))  # fmt: skip
          pending = (requests, pool.submit(self._infer, ask))
          requests, since, executed, sources = requests + 1, [], [], []
        due = schedule.pop(tick)
        if due is None:
          idle += 1  # (the first tick's action is the first chunk's first: `last` is set by then)
        action, source = due if due is not None else last
        act(action)
        executed.append(np.asarray(action))
        sources.append(source)
        last, tick = (action, source), tick + 1
      if pending is not None:
        pending[1].result()  # (its chunk comes too late to execute; the server answers in order)
    self.stats = dict(ticks=tick, idle=idle, dropped=schedule.dropped, requests=requests)
    return dict(self._stack(since), executed=np.stack(executed), executed_from=np.asarray(sources, np.int64))

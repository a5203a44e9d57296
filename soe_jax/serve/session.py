"""What a policy server does per connection, without the network: check an observation against the
policy's spec, keep the connection's observation history, pick a chunk in the request's mode, reply
with its executed actions, and record the episode for a person's label.

A request is the robot's observation dict in raw units: every key of the spec (`data.spec.PolicySpec`:
low-dimensional vectors as float arrays of their shapes, camera images as (H, W, 3) uint8 of any height
and width, which `images.resize_with_pad` brings to the policy's: the aspect ratio kept, black padding)
and any other cameras (`observation.images.*`, uint8 (H, W, 3): shown on the page, and recorded where
the fitted dataset has them, `recorder.kept_keys`), either one observation or, with a leading axis of
k, the k observations taken since the previous request (one after each executed action, so the history
holds consecutive steps and the recorder every step; a client that sends one observation without the
axis after a chunk of several actions, as openpi's `ActionChunkBroker` does, gives the policy a history
of observations a chunk apart, and its episode cannot be recorded); optionally `timestamp` (seconds, of
the latest observation), `episode_start` (true on an episode's first observation; openpi's `reset()`
sends nothing, so the robot says it here) and `mode` (`modes.MODES`, default the server's). Other keys
are ignored, as are `observation.images.*` that are no RGB image (a depth map). A client with real-time
chunks (`client.RealTime`) adds `executed` (k, A), the actions it executed at the steps whose
observations it sends (in the robot's layout), and `executed_from` (k,), the request whose chunk each
came from; the recorder writes those. It keeps one request in flight and needs no more: the
connection's frames are answered in order, so a second request sent meanwhile would wait for the
first's reply. The reply holds chunk-first arrays, as openpi's `ActionChunkBroker(policy,
action_horizon=Ta)` slices:

  actions     (Ta, A) float32   chunk[To-1 : To-1+Ta] in the robot's frame (absolute poses) and its
                                rotation convention (the spec's `robot_actions`, `data.rotations`)
  timestamps  (Ta,)   float64   when each action is due: the observation's timestamp + i / control_hz
  server_timing {"infer_ms": ...}  (added by the server)
  steering    (steer mode only; plain lists, which the broker passes through) {"dims", "proposals"
              (C, Ta, A), "dim_of" (C,), "chosen" (index or None), "timed_out"}

A steer request waits for a person's choice (`chooser`) up to the server's timeout, then executes the
base path for the same key and says so. `{"episode_end": true, "label": "success" | "failure" |
"discard" (or absent: the page labels it), "start_state": n (optional), <observations since>}` ends
the episode; the reply is `{"recorded": ...}` (see `recorder.py`).

The sampling key of request n of episode e is `request_key(seed, instance, e, n)`: the server's seed,
its instance (the microseconds since the epoch when it started, so a restarted server repeats no key)
and the episode's id, counted over all the server's connections (so two connections never share one);
`Keys` hands them out. The recorder writes each frame's (seed, instance, e, n), so a recorded chunk is
sampled again from its recording: a fixed observation history and key give the chunk the policy gives
in-process.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Callable

import jax
import numpy as np

from soe_jax.data.images import resize_with_pad
from soe_jax.data.spec import PolicySpec
from soe_jax.policies import agent as agent_lib
from soe_jax.policies.agent import Agent
from soe_jax.serve import recorder as recorder_lib
from soe_jax.serve.modes import Modes

BOX_TOL = 1e-5  # relative to the box's size: the sampler's clip lands on its faces, in float32
MAX_SINCE = 1024  # observations one request may carry
OPTIONAL_KEYS = ("timestamp (optional)", "episode_start (optional)", "mode (optional)",
                 "executed + executed_from (optional: the actions executed, real-time chunks)",
                 "episode_end + label (ends an episode)")  # fmt: skip


class RequestError(ValueError):
  """The client's request is not what the spec asks for (one line for the error frame)."""


class PolicyError(RuntimeError):
  """The policy's chunk is not fit to send (not finite, or outside the action box)."""


def request_key(seed: int, instance: int, episode: int, request: int) -> jax.Array:
  """The sampling key of request `request` of episode `episode` of the server started as `instance`
  with `seed` (the 64-bit instance folded in as two 32-bit words)."""
  key = jax.random.key(seed)
  for word in (instance >> 32, instance & 0xFFFFFFFF, episode, request):
    key = jax.random.fold_in(key, np.uint32(word))
  return key


class Keys:
  """Where one server's sampling keys come from: its `seed`, its `instance` (default: the microseconds
  since the epoch now, so a server restarted with the same seed repeats no key) and one count of
  episodes over all its connections. Thread-safe."""

  def __init__(self, seed: int = 0, instance: int | None = None):
    self.seed = int(seed)
    self.instance = time.time_ns() // 1000 if instance is None else int(instance)
    if not 0 <= self.instance < 1 << 63:  # (the recording keeps it as an int64)
      raise ValueError(f"instance {self.instance}: a whole number in [0, 2^63)")
    self._episodes = itertools.count()
    self._lock = threading.Lock()

  def new_episode(self) -> int:
    """The next episode's id, unique among this server's connections."""
    with self._lock:
      return next(self._episodes)

  def ids(self, episode: int, request: int) -> tuple[int, int, int, int]:
    """What `request_key` takes for request `request` of episode `episode` (the recorder writes it)."""
    return self.seed, self.instance, int(episode), int(request)


def _scalar(v):
  return v.item() if isinstance(v, np.ndarray) and v.shape == () else v  # openpi packs 0-d arrays so


def _is_camera(value) -> bool:
  """Whether `value` is an RGB camera image, or a stack of them: uint8 (..., H, W, 3)."""
  return isinstance(value, np.ndarray) and value.dtype == np.uint8 and value.ndim in (3, 4) and value.shape[-1] == 3


def observations_of(spec: PolicySpec, obs: dict) -> tuple[list[dict], bool]:
  """A request's raw observations, checked: one, or the k the leading axis holds -> (k dicts of the
  spec's keys (images uint8 at the policy's size, vectors float32) and the other cameras (as sent),
  oldest first; whether they came stacked, i.e. as the observations after each executed action)."""
  if not isinstance(obs, dict):
    raise RequestError(f"a request is a dict of observations, got {type(obs).__name__}")
  missing = [k for k in spec.observations if k not in obs]
  if missing:
    raise RequestError(f"missing observation keys {missing}; the policy reads {list(spec.observations)}")
  arrays, counts, stacks = {}, {}, []
  for key, info in spec.observations.items():
    value = obs[key]
    if not isinstance(value, (np.ndarray, np.generic, list, float, int)):
      raise RequestError(f"observation {key!r} is a {type(value).__name__}, not an array")
    value = np.asarray(value)
    shape = tuple(info["shape"])
    if info.get("image"):
      if not _is_camera(value) or 0 in value.shape:
        raise RequestError(f"image {key!r} must be uint8 height x width x 3 (or k x that), got {value.dtype} "
                           f"{list(value.shape)}")  # fmt: skip
      stacked = value.ndim == 4
      value = resize_with_pad(value, shape[:2])
    else:
      stacked = value.ndim == len(shape) + 1 and value.shape[1:] == shape
      if value.dtype.kind not in "fiu" or (value.shape != shape and not stacked):
        raise RequestError(
          f"observation {key!r} must be numbers of shape {list(shape)} (or k x that), got {value.dtype} {list(value.shape)}"
        )
      if not np.all(np.isfinite(value)):
        raise RequestError(f"observation {key!r} is not finite: {value.tolist()}")
      value = value.astype(np.float32)
    arrays[key] = value if stacked else value[None]
    stacks.append(stacked)
    counts[key] = len(arrays[key])
  k = set(counts.values())
  if len(k) > 1:
    raise RequestError(f"observations since the last request differ in number between keys: {counts}")
  k = k.pop() if k else 1
  if not 1 <= k <= MAX_SINCE:
    raise RequestError(f"{k} observations in one request; between 1 and {MAX_SINCE}")
  if stacks and len(set(stacks)) > 1:
    raise RequestError("some observation keys have the leading axis of observations since the last request, some not")
  stacked = bool(stacks) and stacks[0]
  for key, value in obs.items():
    if isinstance(key, str) and key.startswith("observation.images.") and key not in arrays and _is_camera(value):
      if (value.ndim == 4) != stacked or (stacked and len(value) != k):
        want = f"{k} x height x width x 3" if stacked else "height x width x 3"
        raise RequestError(f"camera {key!r} has shape {list(value.shape)}; beside the other observations: {want}")
      arrays[key] = value if stacked else value[None]
  return [{key: v[i] for key, v in arrays.items()} for i in range(k)], stacked


def executed_of(spec: PolicySpec, obs: dict, k: int) -> tuple[np.ndarray, np.ndarray] | None:
  """A request's `executed` (k, A) actions in the robot's layout and `executed_from` (k,), the request of
  each one's chunk, checked against its k observations (None when it names none: the blocking loop)."""
  if "executed" not in obs and "executed_from" not in obs:
    return None
  if "executed" not in obs or "executed_from" not in obs:
    raise RequestError("executed and executed_from go together: the actions executed and the request of each's chunk")
  dim = sum(size for arm in spec.robot_actions for _, size in arm)
  actions, sources = np.asarray(obs["executed"]), np.asarray(obs["executed_from"])
  if actions.dtype.kind not in "fiu" or actions.shape != (k, dim) or not np.all(np.isfinite(actions)):
    raise RequestError(f"executed must be {k} x {dim} finite numbers (one action after each observation sent), got "
                       f"{actions.dtype} {list(actions.shape)}")  # fmt: skip
  if sources.dtype.kind not in "iu" or sources.shape != (k,):
    raise RequestError(f"executed_from must be {k} whole numbers (the request of each executed action's chunk), got "
                       f"{sources.dtype} {list(sources.shape)}")  # fmt: skip
  return actions.astype(np.float32), sources.astype(np.int64)


def policy_input(spec: PolicySpec, obs: dict):
  """A raw observation dict -> its latest observation as the policy reads it (batch of 1): the low-dim
  vector (1, D) of the spec's keys in order, with {"lowdim", "images"} for an image policy."""
  return _input(spec, observations_of(spec, obs)[0][-1])


def _input(spec: PolicySpec, one: dict):
  parts = [one[k].reshape(-1) for k in spec.lowdim_keys]
  vector = np.concatenate(parts)[None] if parts else np.zeros((1, 0), np.float32)
  images = {k: one[k][None] for k in spec.image_keys}
  return {"lowdim": vector, "images": images} if images else vector


# A steering request's wait: (session, steering dict) -> the chosen proposal's index, or None on timeout.
Chooser = Callable[["Session", dict], "int | None"]


class Session:
  """One connection: its episodes, observation history, requests' keys and recording."""

  def __init__(self, agent: Agent, spec: PolicySpec, keys: Keys | None = None, modes: Modes | None = None,
               default_mode: str = "base", chooser: Chooser | None = None,
               recorder: recorder_lib.Recorder | None = None, name: str = "0"):  # fmt: skip
    self.agent, self.spec, self.name = agent, spec, name
    self.keys = keys if keys is not None else Keys()  # (a server's sessions share one)
    self.modes = modes if modes is not None else Modes(agent, spec)
    self.default_mode = self.modes.check(default_mode)
    self.chooser, self.recorder = chooser, recorder
    self.history = None
    self.episode, self.step = -1, 0  # the connection's episode (the page's number) and request in it
    self.episode_id = -1  # the episode's id among the server's (its keys')
    self.bounds = spec.action_bounds()
    self.kept = recorder_lib.kept_keys(spec)  # what the episode's log keeps of each observation
    self.lock = threading.Lock()  # the page reads what follows while the connection's thread writes it
    self.log: recorder_lib.Episode | None = None  # the episode under way
    self.ended: dict[int, recorder_lib.Episode] = {}  # ended episodes awaiting the page's label
    self.latest: dict | None = None  # the latest observation
    self.cameras: dict[str, np.ndarray] = {}  # the latest camera images, the policy's and others (the page's)
    self.mode = self.default_mode
    self.steering: dict | None = None  # the last steer request (the page shows and answers it)
    self.trail: list[np.ndarray] = []  # the actions sent in the episode under way (the page draws them)
    self.alive: Callable[[], bool] = lambda: True  # whether the robot is still connected
    self.closed = False

  def infer(self, obs: dict) -> dict:
    """The reply to one request (see the module's docstring); RequestError for a bad request,
    PolicyError for a chunk that must not be sent."""
    if isinstance(obs, dict) and _scalar(obs.get("episode_end", False)) is True:
      return self.end(obs)
    observations, stacked = observations_of(self.spec, obs)
    start = _scalar(obs.get("episode_start", False))
    if not isinstance(start, (bool, np.bool_)):
      raise RequestError(f"episode_start must be true or false, got {start!r}")
    executed = executed_of(self.spec, obs, len(observations))
    if executed is not None and start:
      raise RequestError("executed actions with episode_start: an episode's first request follows no action")
    stamp = _scalar(obs.get("timestamp", time.time()))
    if not isinstance(stamp, (int, float, np.number)) or not np.isfinite(stamp):
      raise RequestError(f"timestamp must be a number of seconds, got {stamp!r}")
    mode = _scalar(obs.get("mode", self.default_mode))
    try:
      mode = self.modes.check(mode)
    except ValueError as e:
      raise RequestError(str(e)) from None
    dt = 1.0 / self.spec.control_hz
    stamps = [float(stamp) - dt * (len(observations) - 1 - i) for i in range(len(observations))]
    inputs = [_input(self.spec, o) for o in observations]
    new = start or self.history is None
    history = agent_lib.initial_history(inputs[0], self.agent.policy.n_obs_steps) if new else self.history
    for x in inputs[1:] if new else inputs:
      history = agent_lib.push_history(history, x)
    if new:
      log = recorder_lib.Episode(self.episode + 1, observations[-1], stamps[-1], keep=self.recorder is not None,
                                 keys=self.kept)  # fmt: skip
    else:
      log = self.log
      try:
        log.advance(observations, stamps, stacked, executed)
      except recorder_lib.LabelError as e:
        raise RequestError(str(e)) from None
    episode_id = self.keys.new_episode() if new else self.episode_id
    with self.lock:
      if new:
        self.episode, self.step, self.trail, self.episode_id = self.episode + 1, 0, [], episode_id
      self.history, self.log, self.latest, self.mode = history, log, observations[-1], mode
      self.cameras = {k: v for k, v in observations[-1].items() if _is_camera(v)}
    ids = self.keys.ids(self.episode_id, self.step)
    key = request_key(*ids)
    self.step += 1
    steering, actions = None, None
    if mode == "steer":
      proposals, dim_of = jax.device_get(self.modes("steer", self.agent, history, key))
      steering = dict(dims=list(self.modes.dims), proposals=np.asarray(proposals[0], np.float32).tolist(),
                      dim_of=[int(d) for d in dim_of], chosen=None, timed_out=False,
                      request=f"{self.episode}-{self.step - 1}")  # fmt: skip
      with self.lock:
        self.steering = steering
      choice = self.chooser(self, steering) if self.chooser is not None else None
      with self.lock:
        steering.update(chosen=choice, timed_out=choice is None)
      if choice is not None:
        actions = np.asarray(proposals[0][choice], np.float32)
    if actions is None:  # (a steer request nobody answered: the base path, for the same key)
      path = "base" if mode == "steer" else mode
      actions = np.asarray(jax.device_get(self.modes(path, self.agent, history, key))[0], np.float32)
    self.check(actions)
    sent = self.spec.to_robot(actions)  # the robot's rotation convention (the page keeps the policy's)
    log.sent(sent, mode, ids)
    with self.lock:
      self.trail.extend(actions)
    reply = {"actions": sent, "timestamps": float(stamp) + dt * np.arange(len(actions), dtype=np.float64)}
    if steering is not None:
      reply["steering"] = {k: v for k, v in steering.items() if k != "request"}
      if self.spec.robot_rotations is not None:
        reply["steering"]["proposals"] = self.spec.to_robot(steering["proposals"]).tolist()
    return reply

  def end(self, obs: dict) -> dict:
    """`episode_end`: close the episode under way with the observations sent, and save it with its
    label (or keep it for the page's)."""
    if self.log is None:
      raise RequestError("episode_end, but no episode is under way (send its observations with episode_start first)")
    label, start_state = _scalar(obs.get("label")), _scalar(obs.get("start_state"))
    if label is not None and label not in recorder_lib.LABELS:
      raise RequestError(
        f"unknown label {label!r}; known: {', '.join(recorder_lib.LABELS)} (or none: the page labels it)"
      )
    try:
      recorder_lib.check_start_state(start_state)
    except recorder_lib.LabelError as e:
      raise RequestError(str(e)) from None
    has_obs = all(k in obs for k in self.spec.observations)
    observations, stacked = observations_of(self.spec, obs) if has_obs else ([], True)
    executed = executed_of(self.spec, obs, len(observations))
    dt, stamp = 1.0 / self.spec.control_hz, _scalar(obs.get("timestamp", time.time()))
    stamps = [float(stamp) - dt * (len(observations) - 1 - i) for i in range(len(observations))]
    try:
      self.log.advance(observations, stamps, executed=executed)
    except recorder_lib.LabelError as e:
      raise RequestError(str(e)) from None
    log = self.log
    log.start_state = start_state
    with self.lock:
      self.log, self.history = None, None
    if label is None:
      with self.lock:
        self.ended[log.number] = log
      return {"recorded": dict(episode=log.number, label=None, written=False, awaiting_label=True)}
    return {"recorded": dict(episode=log.number, **self.label(log, label, log.start_state))}

  def label(self, log: recorder_lib.Episode, label, start_state=None) -> dict:
    if self.recorder is None:
      if label not in recorder_lib.LABELS:
        raise RequestError(f"unknown label {label!r}; known: {', '.join(recorder_lib.LABELS)}")
      return dict(label=label, written=False, reason="the server is not recording (serve --record=DIR)")
    try:
      return self.recorder.save(log, label, start_state)
    except recorder_lib.LabelError as e:
      raise RequestError(str(e)) from None

  def label_ended(self, episode: int, label, start_state=None) -> dict:
    """The page's label for an ended episode awaiting one."""
    with self.lock:
      log = self.ended.get(episode)
    if log is None:
      raise RequestError(
        f"connection {self.name} has no ended episode {episode} awaiting a label; those awaiting: {sorted(self.ended)}"
      )
    out = self.label(log, label, log.start_state if start_state is None else start_state)
    with self.lock:
      self.ended.pop(episode, None)
    return out

  def check(self, actions: np.ndarray) -> None:
    if not np.all(np.isfinite(actions)):
      raise PolicyError("the policy's chunk is not finite; nothing was sent")
    if self.bounds is not None:
      lo, hi = self.bounds
      tol = BOX_TOL * np.where(np.isfinite(hi - lo), hi - lo, 0.0)
      out = (actions < lo - tol) | (actions > hi + tol)
      if out.any():
        t, d = map(int, np.argwhere(out)[0])
        raise PolicyError(
          f"the policy's action {t} leaves the action box in dimension {d} ({actions[t, d]:.5f} not in "
          f"[{lo[d]:.5f}, {hi[d]:.5f}]); nothing was sent"
        )


def zero_history(agent: Agent, spec: PolicySpec):
  zeros = {k: np.zeros(v["shape"], np.uint8 if v.get("image") else np.float32) for k, v in spec.observations.items()}
  return agent_lib.initial_history(_input(spec, zeros), agent.policy.n_obs_steps)


def warm_up(agent: Agent, spec: PolicySpec, modes: Modes | None = None) -> None:
  """Compile every mode's chunk for one observation history (before a server listens)."""
  modes = modes if modes is not None else Modes(agent, spec)
  modes.warm_up(agent, zero_history(agent, spec), request_key(0, 0, 0, 0))


def metadata(spec: PolicySpec, agent: Agent, modes: Modes | None = None, default_mode: str = "base") -> dict:
  """The frame sent on connect: the spec, the policy's image size, the chunk's timing, the modes and the
  cameras a recording keeps."""
  p = agent.policy
  return dict(
    server="soe_jax",
    protocol="openpi websocket + msgpack-numpy",
    spec=spec.to_dict(),
    n_obs_steps=p.n_obs_steps,
    horizon=p.horizon,
    action_horizon=p.n_action_steps,
    control_hz=spec.control_hz,
    modes=(modes if modes is not None else Modes(agent, spec)).describe(),
    default_mode=default_mode,
    image_size=list(spec.image_shape) if spec.image_shape else None,  # (height, width); others: resize_with_pad
    request_keys=[*spec.observations, "observation.images.* (optional: other cameras)", *OPTIONAL_KEYS],
    recorded_cameras=[k for k in recorder_lib.kept_keys(spec) if k not in spec.lowdim_keys],  # (with --record)
    reply_keys=["actions", "timestamps", "server_timing", "steering (steer mode)"],
    reply_actions=spec.robot_actions,  # the layout of a reply's actions per arm (the robot's rotation part)
  )

"""What the server saw and sent, written as a LeRobotDataset once a person labels it.

An episode, as one connection's requests make it: the first observation (`episode_start`), then each
request carries the observations taken since the previous one (each observation key with a leading
axis of k, or one observation), one after each action executed. A frame is an observation and the
action executed from it. A request that says which actions were executed (`executed` (k, A) and
`executed_from` (k,), the request whose chunk each came from: a client with real-time chunks, which
asks for the next chunk while executing this one, aggregates overlapping chunks and holds its last
command when none is due) closes k frames with those; one that does not (the blocking loop) closes k
frames of the previous reply's first k actions. `end` closes the last frames with the observations
(and executed actions) sent with it.

A labelled episode (success / failure; a discarded one is dropped) is saved losslessly as
`<dir>/episodes/<n>.npz` (written whole, then renamed), and the LeRobotDataset `<dir>/lerobot` is
written again from all of them (to a new directory, swapped in by rename): a crash leaves the last
complete dataset. Per frame it holds the observations, the action sent (absolute), `next.success` on a
successful episode's last frame, and the columns `mode` (index into `modes.MODES`), `robot_time` (the
observation's timestamp), `start_state` (the attempt group a person gave, -1 when none), which
`refit.select=first_success` and `python -m soe_jax table1` group tries by, and `request_key` (seed,
instance, episode id, request: `session.request_key` of them is the key the frame's action was
sampled with, for an aggregated action the newest chunk's; -1s in episodes recorded before the column
existed), and `decision` (1 on each frame whose observation a request's chunk was sampled from, the
step the policy decided at, 0 on the others; -1 in episodes recorded before the column existed). In
the blocking loop a decision is its reply's first frame, and a re-fit's windows aligned to decisions
hold one chunk as sampled (`rounds.aligned_windows`); with real-time chunks the action executed at a
decision is an earlier chunk's (the reply comes later), and the frames' `request_key` says so.

Cameras and names: the policy's cameras are kept as the policy read them (at its size), and each other
camera of the dataset the policy was fitted on (`spec.source`) as the robot sent it, when the robot sent
it with every observation of the episode (every episode of a recording holds the same cameras, of one
size each); the dataset's robot type, its feature names and its task (when it has one; `task` replaces
it) are written with them, so the recording reads like the dataset it continues. A camera the fitted
dataset lacks is shown on the page and not recorded: a re-fit reading every `observation.*` feature
would find a feature the policy's spec does not have.
"""

from __future__ import annotations

import glob
import os
import shutil
import tempfile
import threading

import numpy as np

from soe_jax.data.spec import PolicySpec
from soe_jax.serve.modes import MODES

LABELS = ("success", "failure", "discard")
NO_KEY = (-1, -1, -1, -1)  # a request's key ids, where none is known


class LabelError(ValueError):
  """A label the recorder refuses (one line); nothing was written."""


class CameraError(LabelError):
  """An episode whose cameras cannot join the recording (one line); it is not written."""


def check_start_state(start_state) -> int:
  """The attempt group a person gave (-1 for none)."""
  if start_state is None:
    return -1
  if isinstance(start_state, bool) or not isinstance(start_state, (int, np.integer)) or start_state < 0:
    raise LabelError(f"start_state must be a whole number >= 0 (the attempt group), got {start_state!r}")
  return int(start_state)


def kept_keys(spec: PolicySpec) -> tuple[str, ...]:
  """The observation keys a recording keeps: the policy's, then the other cameras of the dataset it was
  fitted on (`spec.source`)."""
  features = (spec.source or {}).get("features", {})
  cameras = [k for k, f in features.items() if f.get("dtype") in ("video", "image") and k not in spec.observations]
  return (*spec.observations, *cameras)


class Episode:
  """One connection's episode as the server saw it: of each observation, the keys `keys` (None: all)."""

  def __init__(self, number: int, observation: dict, stamp: float, keep: bool = True, keys=None):
    self.number, self.keep = number, keep  # keep: hold the frames (a server that records)
    self.keys = None if keys is None else tuple(keys)
    observation = self._kept(observation)
    # (observation, action, robot time, mode, the request's key ids (seed, instance, episode, request),
    # whether the policy decided at this frame: a request's chunk was sampled from its observation)
    self.frames: list[tuple[dict, np.ndarray, float, int, tuple, bool]] = []
    self.current, self.current_time = observation, float(stamp)
    self.decided = False  # whether a request's chunk was sampled from `current`
    self.pending = None  # (actions (Ta, A), mode index, key ids) of the last reply
    self.replies: list[tuple[int, tuple]] = []  # (mode index, key ids) of each reply, by request
    self.start_state = None  # the attempt group, when the robot names it at the end
    self.gaps: str | None = None  # why the frames are not every step's, if they are not

  def _kept(self, observation: dict) -> dict:
    return observation if self.keys is None else {k: observation[k] for k in self.keys if k in observation}

  def sent(self, actions: np.ndarray, mode: str, key: tuple = NO_KEY) -> None:
    """The reply to a request sampled from the latest observation (`current`): a decision."""
    self.pending = (np.asarray(actions, np.float32), MODES.index(mode), tuple(key))
    self.replies.append(self.pending[1:])
    self.decided = True

  def advance(self, observations: list[dict], stamps: list[float], stacked: bool = True, executed=None) -> None:
    """Close frames with the k observations taken after each of k actions: those `executed` (actions
    (k, A), the request of each's chunk (k,)) or, without it, the last reply's first k (`stacked`: the
    observations came with the leading axis that says so). One observation without that axis after a
    reply of several actions says nothing of the steps between (openpi's `ActionChunkBroker` sends so):
    the episode has gaps, and is refused when labelled rather than written wrong."""
    if executed is not None:
      actions, sources = executed
      if len(actions) != len(observations):
        raise LabelError(f"{len(actions)} executed actions with {len(observations)} observations: send one after each")
      if bad := [int(r) for r in sources if not 0 <= r < len(self.replies)]:
        raise LabelError(f"executed_from names request {bad[0]}, but this episode's requests are 0 to "
                         f"{len(self.replies) - 1}")  # fmt: skip
      self._close(observations, stamps, [(a, *self.replies[int(r)]) for a, r in zip(actions, sources)])
      self.pending = None
      return
    if observations and not stacked and self.pending is not None and len(self.pending[0]) > 1:
      self.gaps = self.gaps or (f"one observation without the leading axis after a reply of {len(self.pending[0])} "
                                "actions")  # fmt: skip
    if self.pending is None:
      if observations:
        raise LabelError("observations arrived with no reply before them")
      return
    actions, mode, key = self.pending
    if len(observations) > len(actions):
      raise LabelError(f"{len(observations)} observations since the last reply, which sent {len(actions)} actions")
    self._close(observations, stamps, [(a, mode, key) for a in actions[: len(observations)]])
    self.pending = None

  def _close(self, observations: list[dict], stamps: list[float], actions: list[tuple]) -> None:
    """One frame per (action, mode, key ids) of `actions`: the current observation and that action, then
    the next observation is current."""
    for (action, mode, key), obs, stamp in zip(actions, observations, stamps):
      if self.keep:
        self.frames.append((self.current, np.asarray(action, np.float32), self.current_time, mode, key, self.decided))
      self.current, self.current_time, self.decided = self._kept(obs), float(stamp), False

  def arrays(self, spec: PolicySpec, success: bool, start_state: int) -> dict:
    if self.gaps:
      raise LabelError(f"episode {self.number} was not written: it has gaps ({self.gaps}); send the observations "
                       "taken after each executed action (soe_jax/serve/client.py does)")  # fmt: skip
    if not self.frames:
      raise LabelError(f"episode {self.number} has no executed step (send the observations after its actions)")
    t = len(self.frames)
    obs = {k: np.stack([f[0][k] for f in self.frames]) for k in spec.observations}
    for k in kept_keys(spec)[len(spec.observations) :]:
      images = [f[0][k] for f in self.frames if k in f[0]]
      if images and (len(images) < t or len({x.shape for x in images}) > 1):
        shapes = sorted({tuple(x.shape) for x in images})
        raise CameraError(f"camera {k!r} came with {len(images)} of its {t} observations, of shapes {shapes}: send it "
                          "with every observation at one size, or never")  # fmt: skip
      if images:
        obs[k] = np.stack(images)
    return dict(
      obs=obs,
      actions=np.stack([f[1] for f in self.frames]),
      success=bool(success),
      columns=dict(
        mode=np.asarray([f[3] for f in self.frames], np.int64),
        robot_time=np.asarray([f[2] for f in self.frames], np.float64),
        start_state=np.full(t, int(start_state), np.int64),
        request_key=np.asarray([f[4] for f in self.frames], np.int64).reshape(t, 4),
        decision=np.asarray([f[5] for f in self.frames], np.int64),
      ),
    )


class Recorder:
  """Labelled episodes of every connection of one server, saved under `directory`."""

  def __init__(self, directory: str, spec: PolicySpec, task: str = "", codec: str = "h264"):
    """`task`: the episodes' task ("": the fitted dataset's, where it has one task)."""
    source = spec.source or {}
    tasks = source.get("tasks") or []
    self.task = task or (tasks[0] if len(tasks) == 1 else "")
    self.robot_type = source.get("robot_type") or "unknown"
    self.names = {k: f["names"] for k, f in source.get("features", {}).items() if f.get("names") is not None}
    self.directory, self.spec, self.codec = os.path.abspath(directory), spec, codec
    if bad := [k for k in spec.observations if not k.startswith("observation.")]:
      raise LabelError(f"the policy's observations {bad} are not LeRobot features (observation.<name>): record "
                       "a policy fitted with `fit` on a LeRobotDataset")  # fmt: skip
    self.lock = threading.Lock()
    os.makedirs(os.path.join(self.directory, "episodes"), exist_ok=True)
    for stale in glob.glob(os.path.join(self.directory, "episodes", ".*.tmp*")):
      os.remove(stale)  # a save cut midway: its episode was never labelled written
    self.saved = len(self._episode_files())
    self.cameras = self._cameras(self._episode_files()[0]) if self.saved else None  # the recording's other cameras

  @property
  def dataset(self) -> str:
    return os.path.join(self.directory, "lerobot")

  def _episode_files(self) -> list[str]:
    return sorted(glob.glob(os.path.join(self.directory, "episodes", "*.npz")))

  def _cameras(self, path: str) -> dict:
    """{camera: frame shape} of the cameras beyond the policy's in the saved episode at `path`."""
    with np.load(path) as z:
      return {k[4:]: z[k].shape[1:] for k in z.files if k.startswith("obs/") and k[4:] not in self.spec.observations}

  def save(self, episode: Episode, label: str, start_state=None) -> dict:
    """Write `episode` with `label` (LABELS) -> {"label", "written", "dataset_episode" (or None)}."""
    if label not in LABELS:
      raise LabelError(f"unknown label {label!r}; known: {', '.join(LABELS)}")
    if label == "discard":
      return dict(label=label, written=False, dataset_episode=None)
    if episode.gaps:
      return dict(label=label, written=False, dataset_episode=None,
                  reason=f"it has gaps ({episode.gaps}): send the observations taken after each executed action")  # fmt: skip
    state = check_start_state(start_state)
    try:
      arrays = episode.arrays(self.spec, label == "success", int(state))
    except CameraError as e:
      return dict(label=label, written=False, dataset_episode=None, reason=str(e))
    cameras = {k: v.shape[1:] for k, v in arrays["obs"].items() if k not in self.spec.observations}
    with self.lock:
      if self.cameras is not None and cameras != self.cameras:
        return dict(label=label, written=False, dataset_episode=None,
                    reason=f"its other cameras {_shapes(cameras)} are not the recording's {_shapes(self.cameras)}")  # fmt: skip
      index = self.saved
      path = os.path.join(self.directory, "episodes", f"{index:06d}.npz")
      fd, tmp = tempfile.mkstemp(prefix=".episode.tmp", dir=os.path.dirname(path))
      with os.fdopen(fd, "wb") as f:
        np.savez_compressed(f, success=arrays["success"], actions=arrays["actions"],
                            **{f"obs/{k}": v for k, v in arrays["obs"].items()},
                            **{f"col/{k}": v for k, v in arrays["columns"].items()})  # fmt: skip
        f.flush()
        os.fsync(f.fileno())
      os.replace(tmp, path)
      self.saved, self.cameras = index + 1, cameras
      self._write_dataset()
    return dict(label=label, written=True, dataset_episode=index)

  def _write_dataset(self) -> None:
    from soe_jax.data import lerobot  # (pyarrow: the `robot` extra; only a recording server needs it)

    episodes = []
    for path in self._episode_files():
      with np.load(path) as z:
        episodes.append(dict(
          obs={k[4:]: z[k] for k in z.files if k.startswith("obs/")},
          actions=z["actions"], success=bool(z["success"]),
          columns={k[4:]: z[k] for k in z.files if k.startswith("col/")}))  # fmt: skip
    for ep in episodes:  # (saved before the column existed: every episode's features must match)
      ep["columns"].setdefault("request_key", np.full((len(ep["actions"]), 4), -1, np.int64))
      ep["columns"].setdefault("decision", np.full(len(ep["actions"]), -1, np.int64))
    fresh = self.dataset + ".new"
    shutil.rmtree(fresh, ignore_errors=True)
    stored = {k: f.get("dtype") for k, f in (self.spec.source or {}).get("features", {}).items()}
    # cameras as videos, but where the fitted dataset stores them as images, or yuv420p cannot (an odd side)
    video = [k for k, v in episodes[0]["obs"].items() if v.ndim == 4 and stored.get(k) != "image" and v.shape[1] % 2 == 0
             and v.shape[2] % 2 == 0]  # fmt: skip
    names = {k: n for k, n in self.names.items() if k == "action" or k in episodes[0]["obs"]}
    lerobot.write_dataset(fresh, episodes, self.spec.control_hz, robot_type=self.robot_type, video_keys=video,
                          codec=self.codec, task=self.task, names=names)  # fmt: skip
    old = self.dataset + ".old"
    shutil.rmtree(old, ignore_errors=True)
    if os.path.exists(self.dataset):
      os.rename(self.dataset, old)
    os.rename(fresh, self.dataset)
    shutil.rmtree(old, ignore_errors=True)


def _shapes(cameras: dict) -> str:
  return "{" + ", ".join(f"{k}: {' x '.join(map(str, shape))}" for k, shape in sorted(cameras.items())) + "}"

"""A pool of renderer processes (`child`) that draws a batch of joint positions, split across them.

`Renderer(model, cameras, height, width, processes)` starts its processes on the first `render`;
`render(qpos)` sends each process a contiguous share of the batch (N, nq) and gathers
{camera: (N, height, width, 3) uint8}; `close()` ends them (they also end when this process does:
they stop at the end of their input). Spread over the host's cores, as MuJoCo's C engine is.
"""

from __future__ import annotations

import atexit
import os
import subprocess
import sys
import tempfile
import threading
import warnings

import numpy as np

from soe_jax.render import child


class RenderError(RuntimeError):
  """A renderer process could not draw; the message carries what it printed."""


class _Process:
  def __init__(self, setup: dict):
    env = dict(os.environ)
    env.setdefault("MUJOCO_GL", "egl")  # headless; the child imports mujoco after this is set
    env.setdefault("LP_NUM_THREADS", "1")  # Mesa's llvmpipe: one thread per process, the pool spreads
    self.log = tempfile.TemporaryFile()
    with warnings.catch_warnings():  # JAX warns of any fork; this one is followed at once by exec
      warnings.filterwarnings("ignore", "os.fork", RuntimeWarning)
      self.proc = subprocess.Popen(
        [sys.executable, "-m", "soe_jax.render.child"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=self.log,
        env=env,
      )
    self.send(setup)
    self.receive()

  def send(self, message) -> None:
    try:
      child.send(self.proc.stdin, message)
    except (BrokenPipeError, OSError):
      self.fail(None)

  def receive(self) -> dict:
    try:
      reply = child.receive(self.proc.stdout)
    except (BrokenPipeError, OSError):
      reply = None
    if reply is None or "error" in reply:
      self.fail(reply)
    return reply

  def fail(self, reply):
    self.proc.kill()
    self.proc.wait()
    self.log.seek(0)
    printed = self.log.read().decode(errors="replace").strip()[-2000:]
    self.log.close()
    why = reply["error"] if reply else f"it exited with status {self.proc.returncode}"
    raise RenderError(f"the renderer failed: {why}" + (f"\n{printed}" if printed else ""))

  def close(self) -> None:
    self.proc.stdin.close()  # the child returns at the end of its input
    try:
      self.proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
      self.proc.kill()
      self.proc.wait()
    self.log.close()


def check_cameras(model, cameras) -> None:
  """A ValueError naming the model's cameras if `cameras` names one it lacks."""
  known = [model.camera(i).name for i in range(model.ncam)]
  missing = [c for c in cameras if c not in known]
  if missing:
    raise ValueError(
      f"unknown camera {', '.join(map(repr, missing))}; the model's cameras: {', '.join(known) or 'none'}"
    )


class Renderer:
  """`cameras` of `model` at `height` x `width`, drawn by `processes` processes (default: one per core);
  `samples` replaces the model's multisampling (MuJoCo's default 4; 0 draws Mesa's llvmpipe 2x faster)."""

  def __init__(
    self,
    model,
    cameras,
    height: int,
    width: int | None = None,
    processes: int | None = None,
    samples: int | None = None,
  ):
    check_cameras(model, cameras)
    self.cameras = tuple(cameras)
    self.height, self.width = int(height), int(width if width is not None else height)
    self.processes = int(processes or os.cpu_count() or 1)
    self._setup = dict(model=model, cameras=self.cameras, height=self.height, width=self.width, samples=samples)
    self._pool: list[_Process] = []
    self._closed = False
    self._lock = threading.Lock()  # one batch at a time: the processes answer in order
    atexit.register(self.close)

  @property
  def started(self) -> bool:
    """Whether the processes are running (they start on the first `render`)."""
    return bool(self._pool)

  def _start(self) -> None:
    if self._closed:
      raise RenderError("the renderer is closed")
    try:
      while len(self._pool) < self.processes:
        self._pool.append(_Process(self._setup))
    except RenderError:
      self.close()
      raise

  def render(self, qpos) -> dict[str, np.ndarray]:
    """{camera: (N, height, width, 3) uint8} for joint positions `qpos` (N, nq) (or (nq,): no N)."""
    qpos = np.asarray(qpos, np.float64)
    single = qpos.ndim == 1
    qpos = qpos.reshape(-1, qpos.shape[-1])
    with self._lock:
      self._start()
      shares = [s for s in np.array_split(np.arange(len(qpos)), len(self._pool)) if len(s)]
      try:
        for proc, share in zip(self._pool, shares):
          proc.send(dict(qpos=qpos[share]))
        replies = [proc.receive()["images"] for proc, _ in zip(self._pool, shares)]
      except RenderError:
        self.close()
        raise
    out = {
      c: np.concatenate([r[c] for r in replies]) if replies else np.empty((0, self.height, self.width, 3), np.uint8)
      for c in self.cameras
    }
    return {c: v[0] for c, v in out.items()} if single else out

  def close(self) -> None:
    self._closed = True
    pool, self._pool = self._pool, []
    for proc in pool:
      if proc.proc.poll() is None:
        proc.close()

  def __enter__(self) -> Renderer:
    return self

  def __exit__(self, *exc) -> None:
    self.close()

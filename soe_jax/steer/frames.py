"""Frames of the scene, drawn by a process of their own.

Without a GPU, EGL renders with Mesa's llvmpipe, which loads a second LLVM (libLLVM) into the
process that renders, beside XLA's; two LLVMs in one process are a known way to crash a renderer
(MuJoCo's issue 791). So the steering page's frames come from a child process that imports mujoco
and nothing of JAX: `Frames(model, size, camera)` starts it, `png(qpos)` draws the scene at those
joint positions and returns the PNG, `close()` ends it (it also ends when its parent does: it stops
at the end of its input).

  python -m soe_jax.steer.frames      the child; it reads its messages from standard input
"""

from __future__ import annotations

import os
import pickle
import struct
import subprocess
import sys
import tempfile

import numpy as np

_HEADER = struct.Struct("<Q")


class FrameError(RuntimeError):
  """The child could not draw; the message carries what it printed."""


def _send(stream, obj) -> None:
  data = pickle.dumps(obj)
  stream.write(_HEADER.pack(len(data)) + data)
  stream.flush()


def _receive(stream):
  header = stream.read(_HEADER.size)
  if len(header) < _HEADER.size:
    return None  # the other side closed the pipe
  (size,) = _HEADER.unpack(header)
  return pickle.loads(stream.read(size))


class Frames:
  def __init__(self, model, size: int, camera: str):
    env = dict(os.environ)
    env.setdefault("MUJOCO_GL", "egl")  # headless; the child imports mujoco after this is set
    self._log = tempfile.TemporaryFile()
    self._child = subprocess.Popen(
      [sys.executable, "-m", "soe_jax.steer.frames"],
      stdin=subprocess.PIPE,
      stdout=subprocess.PIPE,
      stderr=self._log,
      env=env,
    )
    self._request(dict(model=model, size=int(size), camera=camera))

  def _request(self, message):
    if self._child is None:
      raise FrameError("the frame renderer is closed")
    try:
      _send(self._child.stdin, message)
      reply = _receive(self._child.stdout)
    except (BrokenPipeError, OSError):
      reply = None
    if reply is None or "error" in reply:
      self._child.kill()
      self._child.wait()
      self._log.seek(0)
      printed = self._log.read().decode(errors="replace").strip()[-2000:]
      why = reply["error"] if reply else f"it exited with status {self._child.returncode}"
      self._child = None
      raise FrameError(f"the frame renderer failed: {why}" + (f"\n{printed}" if printed else ""))
    return reply

  def png(self, qpos: np.ndarray) -> bytes:
    """The scene from the camera with the joints at `qpos` (all other state from the model)."""
    return self._request(dict(qpos=np.asarray(qpos, np.float64)))["png"]

  def close(self) -> None:
    if self._child is not None:
      self._child.stdin.close()  # the child returns at the end of its input
      try:
        self._child.wait(timeout=10)
      except subprocess.TimeoutExpired:
        self._child.kill()
        self._child.wait()
      self._child = None
    self._log.close()

  def __enter__(self) -> Frames:
    return self

  def __exit__(self, *exc) -> None:
    self.close()


def _draw(stdin, stdout) -> None:
  import io

  import matplotlib.image
  import mujoco

  setup = _receive(stdin)
  model, camera = setup["model"], setup["camera"]
  data = mujoco.MjData(model)
  try:
    renderer = mujoco.Renderer(model, setup["size"], setup["size"])
    model.camera(camera)  # an unknown camera fails here, not at the first frame
  except Exception as e:  # whatever the GL stack raised goes back to the parent
    _send(stdout, dict(error=f"{type(e).__name__}: {e}"))
    return
  _send(stdout, dict(ready=True))
  try:
    while (message := _receive(stdin)) is not None:
      data.qpos[:] = message["qpos"]
      mujoco.mj_forward(model, data)
      renderer.update_scene(data, camera=camera)
      buf = io.BytesIO()
      matplotlib.image.imsave(buf, renderer.render(), format="png")
      _send(stdout, dict(png=buf.getvalue()))
  finally:
    renderer.close()  # before the interpreter tears EGL down


if __name__ == "__main__":
  replies = os.fdopen(os.dup(1), "wb")
  os.dup2(2, 1)  # what the libraries print goes to the log, not into the replies
  _draw(sys.stdin.buffer, replies)

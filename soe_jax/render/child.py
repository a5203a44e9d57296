"""One renderer process: it draws a scene's cameras at the joint positions it is sent.

Without a GPU, EGL renders with Mesa's llvmpipe, which loads a second LLVM (libLLVM) into the
process that renders, beside XLA's; two LLVMs in one process are a known way to crash a renderer
(MuJoCo's issue 791). So images are drawn by child processes that import mujoco and nothing of JAX
(`pool.Renderer` starts and feeds them).

Messages are length-prefixed pickles over standard input and output: first the setup
`{model, cameras, height, width, samples}` (answered `{ready}` or `{error}`; `samples` replaces the
model's multisampling when not None), then any number of
`{qpos: (n, nq) float64}`, each answered `{images: {camera: (n, height, width, 3) uint8}}` with the
rows top-down (MuJoCo's `Renderer` already flips OpenGL's bottom-up rows, as robomimic stores its
images). Only the kinematics are computed from `qpos` (`mj_kinematics`, `mj_camlight`): what a
camera sees depends on nothing else. The child ends at the end of its input.

  python -m soe_jax.render.child
"""

from __future__ import annotations

import os
import pickle
import struct
import sys

_HEADER = struct.Struct("<Q")


def send(stream, obj) -> None:
  data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
  stream.write(_HEADER.pack(len(data)) + data)
  stream.flush()


def receive(stream):
  """The next message, or None once the other side has closed the pipe."""
  header = stream.read(_HEADER.size)
  if len(header) < _HEADER.size:
    return None
  (size,) = _HEADER.unpack(header)
  return pickle.loads(stream.read(size))


def serve(stdin, stdout) -> None:
  # Here, not at the top: MuJoCo reads MUJOCO_GL when it is imported, and the pool sets it for the child.
  import mujoco
  import numpy as np

  setup = receive(stdin)
  if setup is None:
    return
  model, cameras = setup["model"], list(setup["cameras"])
  height, width = int(setup["height"]), int(setup["width"])
  if setup.get("samples") is not None:
    model.vis.quality.offsamples = int(setup["samples"])
  data = mujoco.MjData(model)
  try:  # (the pool has refused unknown cameras already)
    renderer = mujoco.Renderer(model, height, width)
  except Exception as e:  # whatever the GL stack or the model raised goes back to the parent
    send(stdout, dict(error=f"{type(e).__name__}: {e}"))
    return
  hidden = mujoco.MjvOption()
  hidden.sitegroup[:] = 0  # sites mark frames and targets for people, not for the cameras
  send(stdout, dict(ready=True))
  try:
    while (message := receive(stdin)) is not None:
      qpos = np.asarray(message["qpos"], np.float64)
      images = {c: np.empty((len(qpos), height, width, 3), np.uint8) for c in cameras}
      for i, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_camlight(model, data)
        for camera in cameras:
          renderer.update_scene(data, camera=camera, scene_option=hidden)
          renderer.render(out=images[camera][i])
      send(stdout, dict(images=images))
  finally:
    renderer.close()  # before the interpreter tears EGL down


if __name__ == "__main__":
  replies = os.fdopen(os.dup(1), "wb")
  os.dup2(2, 1)  # what the libraries print goes to the log, not into the replies
  serve(sys.stdin.buffer, replies)

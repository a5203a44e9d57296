"""MuJoCo Warp's batch renderer: a scene's cameras drawn by ray tracing every environment at once.

`WarpRenderer(model, cameras, height, width)` has `pool.Renderer`'s interface (`render(qpos)` ->
{camera: (N, height, width, 3) uint8, rows top-down}, `close()`), and runs on a CUDA GPU when warp-lang
sees one, on Warp's CPU device otherwise (correct there, but single-threaded: ~2.7 ms a frame against
the GL pool's ~0.7 ms per process, BENCHMARKS.md, so `env.renderer=auto` takes it only on a GPU). Only
the kinematics are computed from `qpos`, as the GL pool does.

The ray tracer has no near clipping plane: a camera inside or just outside its own body's geoms (the
in-hand camera sits on the hand) would see them fill the frame, where OpenGL clips them at `znear`.
So each camera draws the scene without the geoms welded to its body that come within `znear` of it
(`near_geoms`), and a camera is one render context. Batches run in blocks of a power of two (at most
`BLOCK` environments; the last padded), so a few contexts serve every batch size."""

from __future__ import annotations

import copy
import threading

import mujoco
import numpy as np

from soe_jax.render import pool

BLOCK = 1024
_HIDDEN_GROUP = 3  # a geom group neither OpenGL's default options nor the contexts below draw
_DRAWN_GROUPS = [0, 1, 2]


def near_geoms(model: mujoco.MjModel, camera: str) -> list[int]:
  """The geoms rigidly attached to `camera`'s body whose bounding sphere reaches within the near plane
  (`vis.map.znear` x the model's extent) of the camera: what OpenGL clips from its view."""
  cam = model.camera(camera).id
  data = mujoco.MjData(model)
  mujoco.mj_kinematics(model, data)
  mujoco.mj_camlight(model, data)
  znear = model.vis.map.znear * model.stat.extent
  weld = model.body_weldid[model.cam_bodyid[cam]]
  gap = np.linalg.norm(data.geom_xpos - data.cam_xpos[cam], axis=1) - model.geom_rbound
  return [int(g) for g in np.flatnonzero((model.body_weldid[model.geom_bodyid] == weld) & (gap < znear))]


def device() -> str:
  """Warp's device for rendering: the first CUDA GPU, else the CPU."""
  import warp as wp

  wp.config.quiet = True  # no banner or per-module lines in a run's output
  wp.init()
  return "cuda:0" if wp.get_cuda_device_count() else "cpu"


class WarpRenderer:
  """`cameras` of `model` at `height` x `width`, ray traced by MuJoCo Warp on `device` (default `device()`)."""

  def __init__(self, model, cameras, height: int, width: int | None = None, device: str | None = None):
    pool.check_cameras(model, cameras)
    self.model, self.cameras = model, tuple(cameras)
    self._hidden = {c: near_geoms(model, c) for c in self.cameras}  # what each camera draws without
    self.height, self.width = int(height), int(width if width is not None else height)
    self.device = device
    self._blocks: dict[int, tuple] = {}  # block size -> (warp data, {camera: (context, output)})
    self._lock = threading.Lock()
    self._closed = False

  def _block(self, n: int):
    import warp as wp
    from mujoco.mjx.third_party import mujoco_warp as mjw

    if n not in self._blocks:
      if self.device is None:
        self.device = device()
      with wp.ScopedDevice(self.device):
        if not self._blocks:
          self._model = mjw.put_model(self.model)
        contexts = {}
        for camera in self.cameras:
          seen = copy.copy(self.model)
          seen.geom_group[self._hidden[camera]] = _HIDDEN_GROUP
          rc = mjw.create_render_context(
            seen,
            nworld=n,
            cam_res=(self.width, self.height),
            render_rgb=True,
            render_depth=False,
            cam_active=[camera],
            enabled_geom_groups=_DRAWN_GROUPS,
          )
          contexts[camera] = rc, wp.zeros((n, self.height, self.width), dtype=wp.vec3)
        self._blocks[n] = mjw.make_data(self.model, nworld=n), contexts
    return self._blocks[n]

  def render(self, qpos) -> dict[str, np.ndarray]:
    """{camera: (N, height, width, 3) uint8} for joint positions `qpos` (N, nq) (or (nq,): no N)."""
    import warp as wp
    from mujoco.mjx.third_party import mujoco_warp as mjw

    if self._closed:
      raise RuntimeError("the renderer is closed")
    qpos = np.asarray(qpos, np.float32)
    single = qpos.ndim == 1
    qpos = qpos.reshape(-1, qpos.shape[-1])
    out = {c: np.empty((len(qpos), self.height, self.width, 3), np.uint8) for c in self.cameras}
    with self._lock:
      for start in range(0, len(qpos), BLOCK):
        part = qpos[start : start + BLOCK]
        n = 1 << (len(part) - 1).bit_length()
        data, contexts = self._block(n)
        with wp.ScopedDevice(self.device):
          data.qpos.assign(np.concatenate([part, np.repeat(part[-1:], n - len(part), axis=0)]))
          mjw.kinematics(self._model, data)
          mjw.camlight(self._model, data)
          for camera, (rc, rgb) in contexts.items():
            mjw.refit_bvh(self._model, data, rc)
            mjw.render(self._model, data, rc)
            mjw.get_rgb(rc, 0, rgb)
            out[camera][start : start + len(part)] = np.round(rgb.numpy()[: len(part)] * 255).astype(np.uint8)
    return {c: v[0] for c, v in out.items()} if single else out

  def close(self) -> None:
    self._closed = True
    self._blocks = {}

  def __enter__(self) -> WarpRenderer:
    return self

  def __exit__(self, *exc) -> None:
    self.close()

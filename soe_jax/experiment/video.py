"""Rollout videos: a run's stored episodes rendered from their simulator states to MP4.

Each evaluation and exploration phase stores its first `log.videos` episodes (`RunDir.save_shown`:
robomimic's format, states included). This draws them from the agent view with the in-hand view
beside it, at the control rate (20 frames per second), into `<workdir>/videos/round_<r>_<phase>_<i>.mp4`
(`report.md` links them); the run renders each round's videos as it finishes, and `render_run`
(`python -m soe_jax video`) any round afterwards.
"""

from __future__ import annotations

import os
import re
import subprocess
import warnings
from collections.abc import Iterator

import imageio.v2 as imageio
import imageio_ffmpeg
import numpy as np

from soe_jax.envs import registry as env_registry
from soe_jax.experiment.rundir import RunDir
from soe_jax.render.pool import Renderer
from soe_jax.runtime import atomic, faults
from soe_jax.runtime.errors import UserError

# The tasks' cameras, the agent view then the in-hand view (`manipulation.CAMERAS`; a test keeps the two
# equal), named here so that drawing a run's stored episodes does not import the tasks' module (brax).
CAMERAS = ("agentview", "robot0_eye_in_hand")

FPS = 20  # the control rate
SIZE = 256  # pixels per camera view
PHASES = ("evaluate", "explore")


def video_path(workdir: str, r: int, phase: str, i: int) -> str:
  return os.path.join(workdir, "videos", f"round_{r}_{phase}_{i}.mp4")


def frames(renderer: Renderer, states: np.ndarray, nq: int) -> np.ndarray:
  """(T, size, 2 size, 3) uint8: the episode's states [time, qpos, qvel, ...] (T, .) drawn from the
  agent view, the in-hand view beside it."""
  images = renderer.render(np.asarray(states)[:, 1 : 1 + nq])
  return np.concatenate([images[c] for c in CAMERAS], axis=2)


def write_mp4(path: str, video: np.ndarray, fps: int = FPS) -> None:
  """Write (T, H, W, 3) uint8 frames as H.264 MP4 (imageio-ffmpeg's own encoder), atomically."""
  os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
  with faults.site("videos"), atomic.replacing(path, suffix=".mp4") as tmp, warnings.catch_warnings():
    warnings.filterwarnings("ignore", "os.fork", RuntimeWarning)  # (JAX warns of any fork; ffmpeg's execs)
    imageio.mimwrite(tmp, list(video), fps=fps, codec="libx264", quality=7, macro_block_size=16)


def read_mp4(path: str) -> np.ndarray:
  """The (T, H, W, 3) uint8 frames of an MP4 file, decoded by imageio-ffmpeg's ffmpeg in a child process
  (run to its end here: imageio's own reader leaves the child's pipes open)."""
  command = [imageio_ffmpeg.get_ffmpeg_exe(), "-i", path, "-f", "rawvideo", "-pix_fmt", "rgb24", "-"]
  with warnings.catch_warnings():  # JAX warns of any fork; this one is followed at once by exec
    warnings.filterwarnings("ignore", "os.fork", RuntimeWarning)
    done = subprocess.run(command, capture_output=True)
  size = re.search(rb"Video: .*?, (\d+)x(\d+)", done.stderr)
  if done.returncode or size is None:
    raise UserError(f"{path}: not a video ffmpeg can read: {done.stderr.decode(errors='replace').strip()[-300:]}")
  width, height = map(int, size.groups())
  return np.frombuffer(done.stdout, np.uint8).reshape(-1, height, width, 3)


def render_round(
  run, env, r: int, size: int = SIZE, renderer: Renderer | None = None, redraw: bool = True
) -> list[str]:
  """Draw round r's stored episodes of `run` (a `RunDir`) for task `env` -> the paths written (files
  already there are kept unless `redraw`)."""
  own = renderer is None
  renderer = renderer or Renderer(env.mj_model, CAMERAS, size)
  written = []
  try:
    for phase in PHASES:
      for i, ep in enumerate(run.shown(r, phase)):
        path = video_path(run.path, r, phase, i)
        if redraw or not os.path.exists(path):
          write_mp4(path, frames(renderer, ep["states"], env.mj_model.nq))
          written.append(path)
  finally:
    if own:
      renderer.close()
  return written


def videos(workdir: str, r: int) -> list[tuple[str, int, str]]:
  """Round r's videos on disk: (phase, episode index, path relative to the run) in order."""
  out = []
  for phase in PHASES:
    i = 0
    while os.path.exists(path := video_path(workdir, r, phase, i)):
      out.append((phase, i, os.path.relpath(path, workdir)))
      i += 1
  return out


def render_run(workdir: str, r: int | None = None, size: int = SIZE) -> Iterator[str]:
  """Draw round r's stored episodes of the run in `workdir` again (every round with some when r is
  None; files already there are drawn again) -> each path as it is written. A `UserError`, before
  anything is drawn, when there are none."""
  run = RunDir.open(workdir)
  rounds = [r] if r is not None else run.shown_rounds()
  if not rounds or not any(run.shown(q, p) for q in rounds for p in PHASES):
    raise UserError(
      f"{run.path} has no stored episodes{f' for round {r}' if r is not None else ''} "
      f"(rounds with some: {', '.join(map(str, run.shown_rounds())) or 'none'}; runs store their first log.videos "
      "episodes per phase)"
    )
  env_config = run.config.env.copy_and_resolve_references()
  env_config.backend = "mujoco"  # only the model is needed: nothing is stepped
  env = env_registry.env_from_config(env_config)
  with Renderer(env.mj_model, CAMERAS, size) as renderer:
    for q in rounds:
      yield from render_round(run, env, q, size, renderer)

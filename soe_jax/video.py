"""Rollout videos: a run's stored episodes rendered from their simulator states to MP4.

Each evaluation and exploration phase stores its first `log.videos` episodes (`RunDir.save_shown`:
robomimic's format, states included). This draws them from the agent view with the in-hand view
beside it, at the control rate (20 frames per second), into `<workdir>/videos/round_<r>_<phase>_<i>.mp4`
(`report.md` links them); the run renders each round's videos as it finishes, and

  python -m soe_jax.video --workdir=DIR [--round=R] [--size=256]

renders any round afterwards (all rounds without --round; existing files are drawn again).
"""

from __future__ import annotations

import os
import warnings

import imageio.v2 as imageio
import numpy as np
from absl import flags

from soe_jax import cli
from soe_jax.errors import UserError
from soe_jax.render.pool import Renderer

# The tasks' cameras (`manipulation.CAMERAS`; a test keeps the two equal), named here so that the
# command does not import the tasks before `cli.run` quiets MJX's import.
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
  tmp = f"{path}.tmp-{os.getpid()}.mp4"
  with warnings.catch_warnings():  # JAX warns of any fork; imageio-ffmpeg's is followed at once by exec
    warnings.filterwarnings("ignore", "os.fork", RuntimeWarning)
    imageio.mimwrite(tmp, list(video), fps=fps, codec="libx264", quality=7, macro_block_size=16)
  os.replace(tmp, path)


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


def _define_flags() -> None:
  """The command's flags (defined only when it runs: the run imports this module too)."""
  flags.DEFINE_string("workdir", None, "The run directory.")
  flags.DEFINE_integer("round", None, "The round to render (default: every round with stored episodes).")
  flags.DEFINE_integer("size", SIZE, "Pixels per camera view (height and width).")


def main(argv):
  del argv
  from soe_jax.envs import registry as env_registry
  from soe_jax.rundir import RunDir

  if not flags.FLAGS.workdir:
    raise UserError("--workdir=DIR names the run to render")
  run = RunDir.open(flags.FLAGS.workdir)
  env_config = run.config.env.copy_and_resolve_references()
  env_config.backend = "mujoco"  # only the model is needed: nothing is stepped
  env = env_registry.env_from_config(env_config)
  rounds = [flags.FLAGS.round] if flags.FLAGS.round is not None else run.shown_rounds()
  if not rounds or not any(run.shown(r, p) for r in rounds for p in PHASES):
    raise UserError(
      f"{run.path} has no stored episodes{f' for round {rounds[0]}' if flags.FLAGS.round is not None else ''} "
      f"(rounds with some: {', '.join(map(str, run.shown_rounds())) or 'none'}; runs store their first log.videos "
      "episodes per phase)"
    )
  with Renderer(env.mj_model, CAMERAS, flags.FLAGS.size) as renderer:
    for r in rounds:
      for path in render_round(run, env, r, flags.FLAGS.size, renderer):
        print(path, flush=True)


if __name__ == "__main__":
  _define_flags()
  cli.run(main)

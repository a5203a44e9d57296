"""Rollout videos: a run draws the first episode of each evaluation and exploration to MP4 with one
frame per control step, its report links them with their outcomes, and `python -m soe_jax video` draws a
round again (or says which rounds have episodes)."""

import os
import subprocess
import sys
import warnings

import jax.numpy as jnp
import numpy as np
import pytest

from soe_jax.experiment import video
from soe_jax.experiment.rundir import RunDir
from soe_jax.runtime import faults
from tests.render.test_render import needs_egl

pytestmark = needs_egl


def test_a_run_draws_first_episodes_and_the_report_links_them(smoke_run):
  _, config, workdir, _ = smoke_run
  run = RunDir.open(workdir)
  for r in (0, 1, 2):
    for phase in ("evaluate", "explore") if r else ("evaluate",):
      (episode,) = run.shown(r, phase)
      frames = video.read_mp4(os.path.join(workdir, "videos", f"round_{r}_{phase}_0.mp4"))
      assert len(frames) == len(episode["actions"])  # one frame per control step
      assert frames[0].shape == (256, 512, 3)  # the agent view, the in-hand view beside it
  with open(os.path.join(workdir, "report.md")) as f:
    report = f.read()
  assert "- round 1 explore: [0](videos/round_1_explore_0.mp4) " in report


@pytest.mark.slow
def test_video_command_redraws_a_round_and_names_its_rounds(smoke_run, tmp_path):
  """`python -m soe_jax video` draws a round again, and names the rounds it has episodes of when asked for another."""
  _, _, workdir, _ = smoke_run
  path = os.path.join(workdir, "videos", "round_2_evaluate_0.mp4")
  os.remove(path)
  cmd = [sys.executable, "-m", "soe_jax", "video", f"--workdir={workdir}", "--round=2", "--size=64"]
  done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
  assert done.returncode == 0, done.stderr
  written = done.stdout.splitlines()
  assert os.path.abspath(path) in written  # (with round 2's exploration episode's)
  assert all(w.startswith(os.path.abspath(os.path.join(workdir, "videos"))) for w in written)  # nothing else
  assert "warp" not in done.stderr
  assert video.read_mp4(path)[0].shape == (64, 128, 3)  # both views at --size
  cmd[5] = "--round=7"
  done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
  assert done.returncode == 2 and "no stored episodes for round 7 (rounds with some: 0, 1, 2;" in done.stderr


def test_writing_and_reading_a_video_raise_no_warning(tmp_path):
  """Not JAX's os.fork warning (imageio-ffmpeg's encoder and decoder are child processes), nor an
  unclosed pipe."""
  jnp.zeros(1).block_until_ready()  # JAX's threads are up: it would warn of a fork now
  with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    video.write_mp4(str(tmp_path / "v.mp4"), np.zeros((3, 16, 16, 3), np.uint8))
    frames = video.read_mp4(str(tmp_path / "v.mp4"))
  assert not [str(w.message) for w in caught], [str(w.message) for w in caught]
  assert frames.shape == (3, 16, 16, 3)


def test_a_video_killed_midway_leaves_the_old_one_whole(tmp_path, monkeypatch):
  """The write site `videos`: a failure at its `during` point (the new file written, not yet renamed)
  leaves the old video and no temporary file."""
  path = str(tmp_path / "v.mp4")
  video.write_mp4(path, np.zeros((3, 16, 16, 3), np.uint8))
  before = open(path, "rb").read()

  def fail():
    raise OSError("killed here")

  monkeypatch.setattr(faults, "during", fail)
  with pytest.raises(OSError):
    video.write_mp4(path, np.full((5, 16, 16, 3), 255, np.uint8))
  assert os.listdir(tmp_path) == ["v.mp4"] and open(path, "rb").read() == before

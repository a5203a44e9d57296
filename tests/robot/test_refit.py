"""`refit` through its command line: `--config.rounds.<field>` overrides the run's re-fit fields and is
recorded in the round's fit.json; a run saved before the fields had the simulated runs' names refits;
windows aligned to decisions fall back to every window, with a warning, for recorded episodes without
the recorder's decisions; `--episode_modes` keeps one mode's episodes of a recording that
mixes modes, which without it is taken whole with a warning; mistakes are one line and write nothing."""

import json
import logging
import os
import shutil

import ml_collections
import numpy as np
import pytest

from soe_jax import __main__ as entry
from soe_jax.data import lerobot
from soe_jax.data.episodes import EpisodeSet
from soe_jax.robot import config as robot_config
from soe_jax.robot import run
from soe_jax.serve.modes import MODES
from tests.robot import synthetic

# The recording: SOE episodes (success, failure, success) and SIME episodes (success, failure).
RECORDED = [("soe", True), ("soe", False), ("soe", True), ("sime", True), ("sime", False)]


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
  root = tmp_path_factory.mktemp("refit")
  rng = np.random.default_rng(0)
  lerobot.write_dataset(str(root / "demos"), synthetic.episodes(rng, 4, 24, False), fps=10)
  config = robot_config.config("smoke")
  config.policy.head = ml_collections.ConfigDict(dict(name="mlp", kwargs=dict(hidden=(32, 32))))  # (compiles fast)
  config.dataset.update(path=str(root / "demos"))
  run.fit(config, str(root / "run"), progress=False)
  episodes = synthetic.episodes(rng, len(RECORDED), 16, False, [s for _, s in RECORDED])
  for ep, (mode, _) in zip(episodes, RECORDED):
    ep["columns"] = {"mode": np.full(16, MODES.index(mode), np.int64)}
  lerobot.write_dataset(str(root / "recorded"), episodes, fps=10)
  return str(root / "run"), str(root / "recorded")


def _copy(fitted, tmp_path) -> str:
  workdir = str(tmp_path / "run")
  shutil.copytree(fitted[0], workdir)
  return workdir


def _refit(workdir, recorded, *flags):
  entry.main(["soe_jax", "refit", f"--workdir={workdir}", f"--episodes={recorded}", "--noprogress", *flags])


def test_refit_overrides_its_fields_and_keeps_one_modes_episodes(fitted, tmp_path, capsys, caplog):
  workdir = _copy(fitted, tmp_path)
  with caplog.at_level(logging.WARNING):
    _refit(workdir, fitted[1], "--config.rounds.refit_steps=7", "--config.refit.lr=1e-4", "--episode_modes=soe")
  assert "mixes modes" not in caplog.text
  record = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
  saved = json.load(open(os.path.join(workdir, "rounds", "1", "fit.json")))
  assert saved["steps"] == record["steps"] == 7 and len(saved["loss_curve"]) > 0
  assert saved["overrides"] == {"rounds.refit_steps": 7, "rounds.refit_lr": 1e-4}  # (an old name, renamed)
  assert saved["rounds"] == dict(robot_config.config("smoke").rounds.to_dict(), refit_steps=7, refit_lr=1e-4)
  assert saved["episode_modes"] == ["soe"] and saved["episodes_by_source"] == {"0": 4, "1": 2}
  data = json.load(open(os.path.join(workdir, "rounds", "1", "data.json")))
  assert data["episodes"] == [0, 2] and data["episode_modes"] == ["soe"]
  # The run's own config is as `fit` saved it: an override is the round's, recorded with it.
  assert json.load(open(os.path.join(workdir, "config.json")))["rounds"]["refit_steps"] == 20


def test_a_mixed_recording_is_taken_whole_with_a_warning(fitted, tmp_path, caplog):
  workdir = _copy(fitted, tmp_path)
  with caplog.at_level(logging.WARNING):
    record = run.refit(workdir, fitted[1], progress=False)
  assert record["episodes_by_source"] == {"0": 4, "1": 3} and record["overrides"] == {}
  assert "mixes modes" in caplog.text and "soe: 3 episodes, 2 successes" in caplog.text
  assert "sime: 2 episodes, 1 success" in caplog.text and "--episode_modes" in caplog.text


@pytest.mark.parametrize(
  "flag, message",
  [
    (
      "--config.rounds.stepz=5",
      "rounds.stepz: not a re-fit field of the run; its re-fit fields: rounds.aligned_windows, rounds.demo_fraction",
    ),
    ("--config.fit.lr=0.1", "fit.lr: not a re-fit field of the run"),
    ("--config.rounds.refit_steps=many", "rounds.refit_steps"),
    ("--episode_modes=explore", "--episode_modes: unknown mode 'explore'; known: base, soe, sime, steer, recorded"),
    ("--episode_modes=steer", "no episode of mode steer; its episodes' modes: sime 2, soe 3"),
  ],
)
def test_refit_mistakes_are_one_line_and_write_nothing(fitted, tmp_path, capsys, flag, message):
  workdir = _copy(fitted, tmp_path)
  with pytest.raises(SystemExit) as e:
    _refit(workdir, fitted[1], flag)
  err = capsys.readouterr().err
  assert e.value.code == 2 and err.startswith("error: ") and message in err, err
  assert not os.path.exists(os.path.join(workdir, "rounds", "1"))


def test_a_run_saved_with_the_old_field_names_refits(fitted, tmp_path):
  """config.json as `fit` wrote it before the re-fit fields took the simulated runs' names (`refit.*`)."""
  workdir = _copy(fitted, tmp_path)
  path = os.path.join(workdir, "config.json")
  saved = json.load(open(path))
  rounds = saved.pop("rounds")
  saved["refit"] = dict(select=rounds["select"], mode=rounds["refit"], steps=9, lr=rounds["refit_lr"],
                        ema=rounds["refit_ema"])  # fmt: skip
  json.dump(saved, open(path, "w"))
  record = run.refit(workdir, fitted[1], progress=False, episode_modes=["soe"])
  assert record["steps"] == 9 and record["rounds"]["refit_steps"] == 9
  assert record["rounds"]["aligned_windows"] is False  # (what a config without the field did)


def test_aligned_windows_need_the_recorded_decisions(fitted, tmp_path, caplog):
  """The recording has no `decision` feature: every window is drawn, and the record says so."""
  workdir = _copy(fitted, tmp_path)
  with caplog.at_level(logging.WARNING):
    record = run.refit(workdir, fitted[1], False, overrides={"rounds.aligned_windows": True}, episode_modes=["soe"])
  assert "2 recorded episodes (round 1 episode 0, round 1 episode 2) have no decisions every" in caplog.text
  assert record["rounds"]["aligned_windows"] is False and record["overrides"] == {"rounds.aligned_windows": True}


def test_decisions_every_chunk_from_the_first_are_aligned():
  def episode(decision):
    return {"actions": np.zeros((6, 2)), "columns": {} if decision is None else {"decision": np.asarray(decision)},
            "episode_index": 0}  # fmt: skip

  ok, partial, none, old = episode([1, 0, 0, 1, 0, 0]), episode([1, 0, 1, 0, 0, 1]), episode(None), episode([-1] * 6)
  assert run._without_decisions([EpisodeSet([ok], 1)], 3) == []
  assert run._without_decisions([EpisodeSet([ok, partial, none, old], 2)], 3) == [
    "round 2 episode 0", "round 2 episode 0", "round 2 episode 0"]  # fmt: skip

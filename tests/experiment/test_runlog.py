"""The run's console progress: round r of R, elapsed time, and the time left at the measured pace."""

import pytest

from soe_jax.experiment import runlog


def test_round_clock_estimates_rounds_left_from_the_rounds_run(capsys, monkeypatch):
  now = iter([0.0, 0.0, 600.0, 700.0, 820.0])  # start; round 0 at 0 s, 1 at 600 s, 2 at 700 s, 3 at 820 s
  monkeypatch.setattr(runlog.time, "perf_counter", lambda: next(now))
  clock = runlog.RoundClock(3)
  for r in range(4):
    clock.begin(r)
  lines = capsys.readouterr().out.splitlines()
  assert lines[:2] == ["== round 0 of 3 (elapsed 0m00s)", "== round 1 of 3 (elapsed 10m00s)"]
  assert lines[2] == "== round 2 of 3 (elapsed 11m40s, about 3m20s left)"  # round 1 took 100 s; 2 rounds left
  assert lines[3] == "== round 3 of 3 (elapsed 13m40s, about 1m50s left)"  # mean of 100 s and 120 s


@pytest.mark.slow
def test_wandb_mirrors_each_phase_and_resumes_an_interrupted_run(tmp_path, monkeypatch):
  """wandb mirrors each phase offline, and an interrupted run resumes the same wandb run."""
  import glob
  import os

  import pytest

  wandb = pytest.importorskip("wandb", reason="the wandb extra is not installed: pip install -e '.[wandb]'")
  monkeypatch.setenv("WANDB_MODE", "offline")
  monkeypatch.delenv("WANDB_DIR", raising=False)
  workdir = str(tmp_path)
  record = dict(
    round=0,
    phase="fit",
    method="soe",
    final_loss=0.0123,
    steps=40,
    num_episodes=4,
    converged=True,
    time_total_s=2.0,
    time_compile_s=1.0,
  )
  with runlog.RunLog(workdir, runlog.WandbLog(workdir, {"seed": 3}, "soe_jax-test")) as log:
    log.write(record)
  run_id = open(os.path.join(workdir, runlog.WandbLog.ID_FILE)).read()
  with runlog.RunLog(workdir, runlog.WandbLog(workdir, {"seed": 3}, "soe_jax-test")) as log:  # resumed
    log.write(dict(record, round=1, kl=0.5))
  wandb.teardown()  # finish() can return before wandb's writer process has flushed the files; this waits for it to exit
  runs = glob.glob(os.path.join(workdir, "wandb", f"offline-run-*-{run_id}*"))
  assert len(runs) == 2  # both sessions logged to the one run id, on disk only
  logged = b"".join(open(f, "rb").read() for r in runs for f in glob.glob(os.path.join(r, "*.wandb")))
  assert b"fit/final_loss" in logged and b"fit/kl" in logged and b"fit/converged" not in logged
  assert b"commit" in logged and b"seed" in logged  # the config, with the commit, in the offline record


def test_a_phases_line_separates_its_groups_of_numbers():
  record = dict(round=1, phase="explore", success_rate=0.3, num_rollouts=500, wilson_low=0.26, wilson_high=0.34,
                pass_at_k=0.7, k=5, rollouts=280, rollouts_mean=2.8, jerk=34.1, num_episodes=26, obs_out_of_range=0.003,
                time_total_s=102.0, time_compile_s=30.0)  # fmt: skip
  line = runlog.summary_line(record)
  assert "jerk 34.1 m/s^3, kept 26; observation features out of range" in line, line
  assert line.startswith("round 1 explore: success 30.0% of 500 [26.0%, 34.0%]; Pass@5 70.0%") and line.endswith(
    " (102 s, compile 30 s)"
  ), line

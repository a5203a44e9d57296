"""The campaign on a real SLURM cluster (`--executor=slurm`): the one-node cluster that `start.sh` starts
on this machine with the committed `slurm.conf` (`.ci/run` starts it; without it these tests skip,
saying why). A toy campaign's runs there equal the `local` executor's state for state, and a cancelled
arm resubmitted finishes with the same numbers."""

import json
import os
import pathlib
import re
import shutil
import subprocess
import time

import pytest

from soe_jax.analysis import campaign, slurm
from tests.experiment import toy, toy_config
from tests.slurm import toy_jobs

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]
SPEC = f"{toy_config.__file__}:smoke"
METHODS = ["control", "dp", "soe"]
# One round; a job asks for one CPU (two run at once on the two-CPU node) and a quarter of a GB.
OVERRIDES = {"rounds.num_rounds": 1, "slurm.cpus": 1, "slurm.mem_gb": 0.25, "slurm.time_min": 15}
SEEDS = ["0", "1"]
ENDED_WITHIN_S = 900


def _slurm(*args: str) -> str:
  return subprocess.run(args, capture_output=True, text=True, check=True, timeout=30).stdout


def _why_no_cluster() -> str | None:
  if not shutil.which("sbatch") or not shutil.which("srun"):
    return "SLURM is not installed (bash tests/slurm/start.sh installs it and starts a test cluster)"
  try:  # (a controller that is not there takes sinfo 10 s to give up on)
    p = subprocess.run(["sinfo", "-h", "-N", "-o", "%T"], capture_output=True, text=True, timeout=3)
  except subprocess.TimeoutExpired:
    return "the SLURM test cluster does not answer (bash tests/slurm/start.sh starts it)"
  if p.returncode or not p.stdout.startswith(("idle", "mixed", "allocated")):
    return f"the SLURM test cluster is not up ({(p.stderr or p.stdout).strip()}; bash tests/slurm/start.sh starts it)"
  return None


@pytest.fixture(scope="module")
def cluster():
  """The test cluster's commands in this process and in its jobs' (the repository on their path), or a skip."""
  saved = dict(os.environ)
  os.environ["SLURM_CONF"] = str(HERE / "slurm.conf")
  os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
  try:
    if reason := _why_no_cluster():
      pytest.skip(reason)
    yield
  finally:
    os.environ.clear()
    os.environ.update(saved)


def _plan(root, results, seeds) -> list[list[campaign.Arm]]:
  return [campaign.arms(s, o, METHODS, str(root), str(results)) for s, o in campaign.grid(SPEC, OVERRIDES, [], seeds)]


def _submit(root, results, seeds) -> list[str]:
  """The toy campaign's jobs queued -> what `submit` said, a line per seed."""
  argv = ["python -m soe_jax campaign", "--executor=slurm"]
  return list(slurm.submit(_plan(root, results, seeds), str(root), argv, within=toy_jobs.registered))


def _wait(root) -> None:
  """Until the cluster has no job left (its jobs are this test's)."""
  deadline = time.monotonic() + ENDED_WITHIN_S
  while _slurm("squeue", "-h", "-o", "%i"):
    if time.monotonic() > deadline:
      logs = "\n".join(p.read_text()[-2000:] for p in sorted(pathlib.Path(root, slurm.LOGS).rglob("*_log.*")))
      pytest.fail(f"jobs still queued after {ENDED_WITHIN_S} s:\n{_slurm('squeue')}\n{logs}")
    time.sleep(1)


def _outcomes(results, seed: int, method: str) -> dict:
  return json.loads((results / "toy" / f"seed{seed}" / method / "outcomes.json").read_text())


@pytest.fixture(scope="module")
def local(tmp_path_factory):
  """The toy campaign (2 seeds x 3 arms) with the `local` executor -> its results folder."""
  out = tmp_path_factory.mktemp("local")
  with toy.registered():
    campaign.run_local([arm for arms in _plan(out / "runs", out / "results", SEEDS) for arm in arms], progress=False)
  return out / "results"


def test_a_campaign_on_slurm_equals_the_local_one_state_for_state(cluster, local, toy_task, tmp_path):
  """Per seed, round 0 is one job and the arms a job array after it (`afterok`); every arm's per-state
  outcomes equal the local executor's, and the table has every run."""
  root, results = tmp_path / "runs", tmp_path / "results"
  lines = _submit(root, results, SEEDS)
  queued = _slurm("squeue", "-h", "-o", "%i %j %T %E")
  _wait(root)
  for seed, line in zip(SEEDS, lines):
    r0 = re.fullmatch(rf"toy seed {seed}: round 0 as job (\d+); after it, 3 arms: (\d+)_0 control, "
                      r"\2_1 dp, \2_2 soe", line)  # fmt: skip
    assert r0, line
    assert re.search(rf"^{r0[2]}_\[0-2\S*\] toy-s{seed}-arm PENDING afterok:{r0[1]}\S*$", queued, re.M), queued
    script = (root / slurm.LOGS / r0[2] / f"{r0[2]}_submission.sh").read_text()
    assert f"#SBATCH --dependency=afterok:{r0[1]}\n" in script and "#SBATCH --array=0-2" in script
    assert all(f"#SBATCH --{asked}\n" in script for asked in ("cpus-per-task=1", "mem=256M", "time=15"))
    assert len(os.listdir(root / "toy" / f"seed{seed}" / "round0")) == 1  # one round 0, made by its job
    for method in METHODS:
      assert _outcomes(results, int(seed), method) == _outcomes(local, int(seed), method), (seed, method)
  made = json.loads((results / "toy" / "seed1" / "soe" / "command.json").read_text())
  assert made["command"] == "python -m soe_jax campaign --executor=slurm" and "--config.seed=1" in made["main_command"]
  table = (results / "comparison.md").read_text()
  assert all(f"| toy | {m} |" in table for m in METHODS) and table.count("| 2 |") >= 3  # 2 seeds a row


def test_a_cancelled_arm_resubmitted_finishes_with_the_same_numbers(cluster, local, toy_task, tmp_path):
  """An arm's job cancelled once its run has started (`scancel`): the same submission again queues that
  arm alone (round 0 is made, the others finished) and its run ends as the local one did."""
  root, results = tmp_path / "runs", tmp_path / "results"
  (line,) = _submit(root, results, ["0"])
  soe = re.search(r"(\d+_2) soe", line)[1]
  started = root / "toy" / "seed0" / "soe" / "config.json"
  deadline = time.monotonic() + ENDED_WITHIN_S
  while not started.exists():
    assert time.monotonic() < deadline, _slurm("squeue")
    time.sleep(0.1)
  _slurm("scancel", soe)
  _wait(root)
  (arm,) = [a for a in _plan(root, results, ["0"])[0] if a.config.method == "soe"]
  assert not arm.finished() and not (results / "toy" / "seed0" / "soe").exists()
  (again,) = _submit(root, results, ["0"])
  assert re.fullmatch(r"toy seed 0: round 0 made; 1 arm: \d+ soe", again), again
  _wait(root)
  for method in METHODS:
    assert _outcomes(results, 0, method) == _outcomes(local, 0, method), method
  (done,) = _submit(root, results, ["0"])
  assert done == "toy seed 0: every arm finished; nothing queued"

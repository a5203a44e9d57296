"""A run beside the committed campaign of its task and preset (`analysis/context.py`): in its report, its
figure and the lines `run` prints last; and the `quick` preset it is meant for."""

import json
import os
import subprocess

import pytest

from soe_jax.analysis import context
from soe_jax.commands import run as run_command
from soe_jax.experiment import loop
from soe_jax.runtime import configfile
from tests.experiment import toy, toy_config

# Per committed seed, each arm's last round on 4 evaluation start states (round 0 the shared base).
BASE = {0: [1, 0, 0, 1], 1: [0, 1, 1, 0], 2: [1, 1, 0, 0]}
LAST = {
  "control": {0: [1, 0, 0, 0], 1: [0, 1, 1, 0], 2: [1, 1, 0, 0]},
  "dp": {0: [1, 1, 0, 0], 1: [0, 1, 0, 0], 2: [1, 1, 0, 1]},
  "sime": {0: [1, 0, 0, 1], 1: [1, 1, 1, 0], 2: [0, 1, 0, 0]},
  "soe": {0: [1, 1, 0, 1], 1: [0, 1, 1, 1], 2: [1, 1, 1, 0]},
}


def _fake_run(path, config: dict, before, after):
  """A finished one-round run directory of `config` with hand-made per-state outcomes."""
  os.makedirs(path)
  json.dump(config, open(os.path.join(path, "config.json"), "w"))
  lines = [dict(round=r, phase="evaluate", success_rate=sum(o) / len(o), num_rollouts=len(o), wilson_low=0.0,
                wilson_high=1.0, time_total_s=1.0) for r, o in ((0, before), (1, after))]  # fmt: skip
  if config["method"] != "control":
    lines.insert(1, dict(round=1, phase="explore", pass_at_k=0.5, k=5, jerk=3.0, rollouts=3, rollouts_mean=1.5,
                         num_episodes=2, kept_length_mean=40.0))  # fmt: skip
  with open(os.path.join(path, "metrics.jsonl"), "w") as f:
    f.writelines(json.dumps(m) + "\n" for m in lines)
  json.dump(dict(evaluate={"0": before, "1": after}, explore={}), open(os.path.join(path, "outcomes.json"), "w"))


def _campaign(root, get_config, presets: str, seeds=(0, 1, 2)) -> str:
  """A committed campaign's results folder: control, dp, sime and soe over `seeds`."""
  for method, by_seed in LAST.items():
    for seed in seeds:
      after = by_seed[seed]
      config = get_config(f"{presets},{method}").to_dict()
      config.update(seed=seed)
      config["rounds"]["num_rounds"] = 1
      _fake_run(os.path.join(root, "toy", f"seed{seed}", method), config, BASE[seed], after)
  return str(root)


def _lift(presets: str):
  return configfile.load(f"configs/lift.py:{presets}")


def test_a_run_reads_against_each_committed_seed_with_the_seed_level_interval(tmp_path):
  """The run's seed stands beside every committed seed, arm by arm, with each arm's seed-level interval
  against the control; its own seed, when committed, is checked state for state."""
  committed = _campaign(tmp_path / "results", _lift, "quick")
  config = _lift("quick,soe").to_dict()
  config["rounds"]["num_rounds"] = 1
  mine = tmp_path / "runs" / "lift-soe-seed7"
  _fake_run(mine, dict(config, seed=7), [1, 1, 0, 0], [1, 1, 1, 1])
  c = context.compare(str(mine), (committed,))
  by = {a["name"]: a for a in c["arms"]}
  assert c["seeds"] == [0, 1, 2] and list(by) == ["round 0", "control", "dp", "sime", "soe"]
  assert by["soe"]["per_seed"] == {0: 0.75, 1: 0.75, 2: 0.75} and by["soe"]["yours"] == 1.0
  assert by["round 0"]["yours"] == 0.5 and by["control"]["yours"] is None
  soe = by["soe"]["test"]  # soe - control per seed: +0.5, +0.25, +0.25; moderated over 5 fits: 8 df
  assert soe.d == pytest.approx((0.5, 0.25, 0.25)) and soe.df == 8 and soe.low < soe.estimate < soe.high
  text = "\n".join(context.lines(c))
  assert "| soe | 100.0% | 75.0% | 75.0% | 75.0% | 75.0% | +33.3 points [" in text, text
  assert "Your soe against your round 0: +50.0 points; on the committed seeds +25.0, +25.0, +25.0 points" in text
  assert "Your seed 7 is not a committed one" in text
  # Seed 0, as committed: the same outcomes, state for state.
  seed0 = tmp_path / "runs" / "lift-soe-seed0"
  _fake_run(seed0, dict(config, seed=0), BASE[0], LAST["soe"][0])
  text = "\n".join(context.lines(context.compare(str(seed0), (committed,))))
  assert "its per-state outcomes match the committed run's round 0 on 4 of 4 states, soe on 4 of 4 states" in text
  assert "(this machine reproduced it)" in text
  # A campaign of one seed so far: each arm's difference from the control, with no interval.
  one = _campaign(tmp_path / "one", _lift, "quick", seeds=(1,))
  text = "\n".join(context.lines(context.compare(str(mine), (one,))))
  assert (
    "over training seed 1:" in text
    and "| soe | 100.0% | 75.0% | 75.0% | +25.0 points (one seed: no interval) |" in text
  )
  # Another preset (the `cpu` run's settings) has no committed campaign here.
  other = tmp_path / "runs" / "lift-soe-cpu"
  _fake_run(other, dict(_lift("cpu,soe").to_dict(), seed=7), [1, 1, 0, 0], [1, 1, 1, 1])
  assert context.compare(str(other), (committed,)) is None
  assert context.compare(str(mine), (str(tmp_path / "nothing"),)) is None


def test_the_report_and_the_last_lines_put_the_run_beside_the_committed_seeds(tmp_path, monkeypatch):
  """A real run (the toy task) of the committed campaign's preset: its report has the section and the
  figure, and the lines `run` prints last hold the same table before the summary."""
  committed = _campaign(tmp_path / "results", toy_config.get_config, "smoke")
  monkeypatch.setattr(context, "COMMITTED", (committed,))
  config = toy_config.get_config("smoke,soe")
  config.update(seed=5)
  config.rounds.num_rounds = 1
  workdir = str(tmp_path / "runs" / "toy-soe-seed5")
  with toy.registered():
    loop.run(config, workdir, progress=False)
  printed = run_command.last_lines(workdir)
  md = open(os.path.join(workdir, "report.md")).read()
  assert "## Your run beside the committed seeds" in md and "![your run beside the committed seeds](context.png)" in md
  assert os.path.getsize(os.path.join(workdir, "context.png")) > 0
  table = [
    line for line in md.splitlines() if line.startswith("| soe |") and "points [" in line
  ]  # (soe against the control)
  assert len(table) == 1 and "| 75.0% | 75.0% | 75.0% | 75.0% |" in table[0], md
  assert printed[0] == f"report: {os.path.join(workdir, 'report.md')}"
  assert table[0] in printed and "Your seed 5 is not a committed one: it is one more seed beside them." in printed
  assert json.loads(printed[-1])["seed"] == 5  # the summary stays the last line


def test_the_quick_preset_is_cpu_shortened_and_only_where_calibrated():
  quick, cpu = configfile.load("configs/lift.py:quick"), configfile.load("configs/lift.py:cpu")
  changed = {
    k
    for k, v in _flat(quick.to_dict()).items()
    if _flat(cpu.to_dict())[k] != v  # everything else is cpu's (protocol, recipe, demonstrations)
  }
  assert changed == {"fit.num_steps", "eval.num_start_states", "explore.num_start_states"}
  assert quick.fit.num_steps < cpu.fit.num_steps and quick.method == "soe"
  assert configfile.load("configs/lift.py:quick,control").rounds.new_data == "none"
  with pytest.raises(ValueError, match="no quick run is calibrated for square"):
    configfile.load("configs/square.py:quick")
  with pytest.raises(ValueError, match="takes no image preset"):
    configfile.load("configs/lift.py:quick,image")


def _flat(d: dict, prefix: str = "") -> dict:
  out = {}
  for k, v in d.items():
    out.update(_flat(v, f"{prefix}{k}.") if isinstance(v, dict) else {f"{prefix}{k}": v})
  return out


def test_the_committed_campaigns_script_runs_each_arm_of_the_quick_preset(tmp_path):
  """`launch/quick.sh SEED` starts the campaign `results/quick/` holds (a stand-in `python` records it)."""
  shim = tmp_path / "bin"
  shim.mkdir()
  (shim / "python").write_text(f'#!/usr/bin/env bash\nprintf "%s\\n" "$@" > "{tmp_path / "argv"}"\n')
  (shim / "python").chmod(0o755)
  env = dict(os.environ, PATH=f"{shim}:{os.environ['PATH']}", RESULTS=str(tmp_path / "results"))
  p = subprocess.run(["bash", "launch/quick.sh", "2", str(tmp_path / "runs")], cwd=configfile.REPO_ROOT, env=env,
                     capture_output=True, text=True)  # fmt: skip
  assert p.returncode == 0, p.stderr
  argv = (tmp_path / "argv").read_text().split()
  assert argv == ["-m", "soe_jax", "campaign", "--config=configs/lift.py:quick", "--seeds=2",
                  "--methods=control,dp,sime,soe", f"--workdir={tmp_path / 'runs'}",
                  f"--results={tmp_path / 'results' / 'quick'}", "--progress=false"]  # fmt: skip
  for method in ("control", "dp", "sime", "soe"):
    assert configfile.load("configs/lift.py:quick", method).method == method

"""The science issues' launch scripts (`launch/why_own_successes.sh`, `launch/protocol.sh`) and
`launch/campaign.sh` start commands that exist with arms that load: every part run with a stand-in
`python` that records its command lines, each campaign line parsed with the campaign's flags and its
methods' configs loaded and checked (nothing run, nothing compiled), so a typo fails here, not an hour
into a campaign."""

import importlib
import os
import pathlib
import subprocess
import sys

import pytest

from soe_jax import __main__ as dispatcher
from soe_jax.analysis import campaign as campaign_lib
from soe_jax.commands import campaign
from soe_jax.runtime import cli, configfile

ROOT = pathlib.Path(__file__).resolve().parents[2]
SEP = "\x1f"


def _run(tmp_path, script: str, *args: str) -> tuple[subprocess.CompletedProcess, list[list[str]]]:
  """`bash launch/SCRIPT ARGS` with a stand-in `python` (`python -c` checks run for real) -> the run and
  the `python -m` command lines it started, each as its argv after `python`."""
  shim, log = tmp_path / "bin", tmp_path / "lines"
  shim.mkdir(exist_ok=True)
  (shim / "python").write_text(
    f'#!/usr/bin/env bash\n[[ $1 == -c ]] && exec "{sys.executable}" "$@"\n'
    f'printf "%s{SEP}" "$@" >> "{log}"; echo >> "{log}"\n'
  )
  (shim / "python").chmod(0o755)
  log.write_text("")
  env = dict(os.environ, PATH=f"{shim}:{os.environ['PATH']}", RESULTS=str(tmp_path / "results"))
  p = subprocess.run(["bash", f"launch/{script}", *args], cwd=ROOT, env=env, capture_output=True, text=True)
  return p, [line.split(SEP)[:-1] for line in log.read_text().splitlines()]


def _lines(tmp_path, script: str, *args: str) -> list[list[str]]:
  """The `python` command lines `bash launch/SCRIPT ARGS` runs, each as its argv after `python`."""
  p, lines = _run(tmp_path, script, *args)
  assert p.returncode == 0, p.stderr
  return lines


def _campaign_configs(monkeypatch, argv: list[str]) -> dict:
  """A `-m soe_jax campaign ...` line parsed with a fresh copy of the command's flags -> its methods'
  configs, loaded and checked as the campaign would before it writes anything."""
  fresh = importlib.reload(campaign)
  monkeypatch.setattr(sys, "argv", [str(ROOT / "soe_jax" / "__main__.py"), *argv[2:]])
  name = "python -m soe_jax campaign"
  assert cli.parse(fresh.FLAGS, [name, *argv[3:]], required=("config",)) == [name]
  spec, overrides = fresh.FLAGS.config_file()
  return campaign_lib.configs(spec, overrides, fresh.FLAGS.methods)[2]


@pytest.fixture
def parsed(monkeypatch, tmp_path):
  monkeypatch.chdir(ROOT)
  try:
    yield lambda script, *args: [
      (argv, _campaign_configs(monkeypatch, argv) if argv[2] == "campaign" else None)
      for argv in _lines(tmp_path, script, *args)
    ]
  finally:
    importlib.reload(campaign)  # (unparsed again, for whoever imports it next)


@pytest.mark.parametrize("part", ["a", "b", "c", "d", "square"])
def test_why_own_successes_refuses_the_cpu_preset_that_adopted_its_findings(monkeypatch, tmp_path, part):
  """Its committed arms were measured before `cpu` adopted beta 1e-5 and aligned windows: under it the
  script starts nothing and names the fields that differ and the commit to run it at."""
  monkeypatch.setenv("BETA", "1e-05")
  p, lines = _run(tmp_path, "why_own_successes.sh", "1", "/tmp/runs-why", part)
  assert p.returncode == 2 and "at commit f21cbfe" in p.stderr and lines == []
  assert "policy.bypass.beta is 1e-05, not 0.001; rounds.aligned_windows is True, not False" in p.stderr


@pytest.mark.parametrize("part", ["a", "b", "c", "d", "square"])
def test_every_part_of_why_own_successes_starts_commands_that_load(parsed, monkeypatch, part):
  """(On the smoke preset, whose arms have the paper's KL weight and unaligned windows, as `cpu` had.)"""
  monkeypatch.setenv("BETA", "1e-05")
  monkeypatch.setenv("CONFIG", "configs/lift.py:smoke")
  monkeypatch.setenv("SQUARE_CONFIG", "configs/square.py:smoke")
  lines = parsed("why_own_successes.sh", "1", "/tmp/runs-why", part)
  commands = {*dispatcher.COMMANDS, *dispatcher.STUDY_COMMANDS}  # (relabel, fidelity, latent: studies' own names)
  assert lines and all(argv[:2] == ["-m", "soe_jax"] and argv[2] in commands for argv, _ in lines)
  configs = [c for _, found in lines if found for c in found.values()]
  task = "square" if part == "square" else "lift"
  assert configs and all(c.seed == 1 and c.env.task == task for c in configs)
  if part == "b":  # each beta's effective dimensions, from the round 0 its campaign arm fitted
    latents = [argv for argv, _ in lines if argv[2] == "latent"]
    assert sorted(a for argv in latents for a in argv if "bypass.beta" in a) == [
      f"--config.policy.bypass.beta={b}" for b in ("0", "0.0001", "0.001", "1e-05")
    ]
    assert all("--config.rounds.round0_dir=/tmp/runs-why-beta/lift/seed1/round0" in argv for argv in latents)
  if part == "c":  # the re-evaluation: start states no experiment had used
    assert {c.eval.seed for c in configs} == {55555}
  if part == "d":  # the re-evaluation: states no experiment had used
    assert {c.eval.seed for c in configs} == {44444}
  if part in ("d", "square"):  # the picked KL weight, alone and with aligned windows, beside soe and the control
    assert len(configs) == 5 and sum(c.method == "control" for c in configs) == 1
    assert {(c.policy.bypass.beta, c.rounds.aligned_windows) for c in configs if c.method != "control"} == {
      (0.001, False),
      (1e-05, False),
      (0.001, True),
      (1e-05, True),
    }
  if part in ("c", "d", "square"):
    assert {c.rounds.aligned_windows for c in configs} == {False, True}


@pytest.mark.parametrize("part", ["sime-count-4", "varied-count-3", "sime-4", "style-3", "picked-count-can-20"])
def test_the_protocol_parts_refuse_the_cpu_preset_that_took_what_they_picked(tmp_path, part):
  p, lines = _run(tmp_path, "protocol.sh", part, "0", "/tmp/runs-protocol")
  commit = "8d0b68b" if part.startswith("picked") else "c0b0bca"
  assert p.returncode == 2 and f"at commit {commit}" in p.stderr and lines == []
  assert "its control arm" in p.stderr and "rounds.refit is 'scratch', not 'continue'" in p.stderr


@pytest.mark.parametrize("part", ["sime-count-10", "varied-count-5", "sime-10", "style-3"])
def test_every_part_of_the_protocol_script_starts_commands_that_load(parsed, monkeypatch, part):
  monkeypatch.setenv("CONFIG", "configs/lift.py:smoke")  # (the first protocol and scripted demonstrations)
  lines = parsed("protocol.sh", part, "2", "/tmp/runs-protocol")
  count = int(part.rsplit("-", 1)[1])
  ((_, configs),) = [(argv, found) for argv, found in lines if found]
  arms = configs.values()
  assert {c.data.num_demos for c in arms} == {count} and "control" in {c.method.split("-")[0] for c in arms}
  if part.startswith("sime"):
    assert all(c.rounds.refit == "scratch" and c.policy.horizon == 20 for c in arms)
  styles = {c.data.demo_style for c in arms}
  expected = {"scripted", "varied"} if part.startswith("style") else {"varied" if "varied" in part else "scripted"}
  assert styles == expected
  for argv, _ in lines:
    if argv[2] == "latent":  # the latent study's configs load too
      spec = next(a.split("=", 1)[1] for a in argv if a.startswith("--config="))
      assert configfile.load(spec).data.demo_style in styles


@pytest.mark.parametrize("task, count", [("lift", 6), ("square", 20)])
def test_the_picked_count_calibration_runs_sime_protocol_on_varied_demonstrations(parsed, monkeypatch, task, count):
  monkeypatch.setenv("PRESET", "smoke")
  ((argv, configs),) = parsed("protocol.sh", f"picked-count-{task}-{count}", "1", "/tmp/runs-protocol")
  (arm,) = configs.values()
  assert arm.method == "control-style_varied-protocol_sime" and arm.env.task == task and arm.seed == 1
  assert arm.data.num_demos == count and arm.data.demo_style == "varied"
  assert arm.rounds.refit == "scratch" and arm.rounds.select == "sime" and arm.policy.n_action_steps == 20
  assert arm.rounds.num_rounds == 0  # round 0 alone
  assert any(a.endswith(f"protocol-count/picked-{task}-n{count}") for a in argv)


@pytest.mark.parametrize(
  "part, task, methods",
  [
    ("main-square", "square", "control dp sime soe soe_steer dp-expert_data soe-expert_data"),
    ("main-can-1", "can", "control dp sime soe"),
    ("main-can-2", "can", "control soe_steer"),
    ("main-square-3", "square", "control dp-expert_data soe-expert_data"),
    ("rounds-lift", "lift", "control dp sime soe"),
    ("rounds-lift-1", "lift", "control dp soe"),
    ("rounds-lift-2", "lift", "control sime"),
  ],
)
def test_the_main_campaigns_parts_run_every_arm_with_its_control_on_new_evaluation_states(parsed, part, task, methods):
  ((argv, configs),) = parsed("protocol.sh", part, "1", "/tmp/runs-protocol")
  assert sorted(c.method for c in configs.values()) == sorted(methods.split())
  rounds = 3 if part.startswith("rounds-lift") else 1
  assert all(c.env.task == task and c.seed == 1 and c.rounds.num_rounds == rounds for c in configs.values())
  assert {c.eval.seed for c in configs.values()} == {33333}  # neither science issue's (77777, 55555)
  assert f"--workdir=/tmp/runs-protocol/{part.removeprefix('main-')}" in argv
  folder = part.replace("main-", "protocol-main/").replace("rounds-", "protocol-rounds/")
  assert any(a.startswith("--results=") and a.endswith(f"/{folder}") for a in argv)


# The decomposition's arms: (re-fit, selection, prediction horizon).
DECOMPOSITION = {
  "control": ("scratch", "sime", 20),
  "soe": ("scratch", "sime", 20),
  "control-refit_continue": ("continue", "sime", 20),
  "soe-refit_continue": ("continue", "sime", 20),
  "soe-select_first_success": ("scratch", "first_success", 20),
  "soe-select_first_success-refit_continue": ("continue", "first_success", 20),
  "control-protocol_continued": ("continue", "first_success", 16),
  "soe-protocol_continued": ("continue", "first_success", 16),
}


def _arms(configs: dict) -> dict:
  return {c.method: (c.rounds.refit, c.rounds.select, c.policy.horizon) for c in configs.values()}


def test_the_decomposition_pairs_each_of_the_picked_protocols_differences_with_its_control(parsed):
  """soe and the control as picked, with the re-fit continued (both), soe with the first protocol's
  selection under either re-fit, and both under the first protocol whole: each soe arm has a control of
  its re-fit and horizons, and each of the three differences is one step between two soe arms."""
  ((argv, configs),) = parsed("protocol.sh", "decompose-lift", "1", "/tmp/runs-protocol")
  assert _arms(configs) == DECOMPOSITION
  assert all(c.data.demo_style == "varied" and c.eval.seed == 33333 and c.seed == 1 for c in configs.values())
  assert "--workdir=/tmp/runs-protocol/decompose-lift" in argv


@pytest.mark.parametrize("half, first_protocol", [("1", False), ("2", True)])
def test_the_decompositions_halves_split_its_arms_by_round_0(parsed, half, first_protocol):
  """A seed that does not fit a session splits into the six arms on the picked round 0 and the first
  protocol's two (each half with its own round 0 and control), written beside each other."""
  ((argv, configs),) = parsed("protocol.sh", f"decompose-lift-{half}", "1", "/tmp/runs-protocol")
  want = {m: a for m, a in DECOMPOSITION.items() if m.endswith("protocol_continued") == first_protocol}
  assert _arms(configs) == want
  assert f"--workdir=/tmp/runs-protocol/decompose-lift-{half}" in argv
  assert any(a.startswith("--results=") and a.endswith("/protocol-decompose/lift") for a in argv)


@pytest.mark.parametrize(
  "part, arms", [("n3", ("control-protocol_continued", "soe-protocol_continued")), ("n3-picked", ("control", "soe"))]
)
def test_the_decompositions_count_arms_run_on_3_varied_demonstrations_in_one_folder(parsed, part, arms):
  """The first protocol's two arms (n3) and soe and the control as picked (n3-picked) on the
  scripted-against-varied campaign's count, on the main campaign's evaluation states, in one folder of
  their own (their arm names differ, so the two pairs do not mix)."""
  ((argv, configs),) = parsed("protocol.sh", f"decompose-lift-{part}", "1", "/tmp/runs-protocol")
  assert _arms(configs) == {m: DECOMPOSITION[m] for m in arms}
  assert {(c.data.num_demos, c.data.demo_style, c.eval.seed) for c in configs.values()} == {(3, "varied", 33333)}
  assert any(a.startswith("--results=") and a.endswith("/protocol-decompose/lift-n3") for a in argv)
  assert f"--workdir=/tmp/runs-protocol/decompose-lift-{part}" in argv


@pytest.mark.parametrize(
  "script, args, says",
  [
    ("protocol.sh", ["bogus-3", "0", "{runs}"], "unknown part"),
    ("protocol.sh", ["sime-x", "0", "{runs}"], "demonstration count"),
    ("protocol.sh", ["main-transport", "0", "{runs}"], "unknown part"),
    ("protocol.sh", ["decompose-lift-3", "0", "{runs}"], "decompose-lift[-1|-2|-n3|-n3-picked]"),
    ("why_own_successes.sh", ["1", "{runs}", "e"], "known: a, b, c, d, square, all"),
    ("why_own_successes.sh", ["1", "{runs}", "d"], "needs BETA"),
    ("why_own_successes.sh", ["1", "{runs}", "square"], "needs BETA"),
  ],
)
def test_a_bad_part_is_refused_before_anything_runs(tmp_path, script, args, says):
  runs = tmp_path / "runs"
  argv = [a.format(runs=runs) for a in args]
  env = {k: v for k, v in os.environ.items() if k != "BETA"}
  p = subprocess.run(["bash", f"launch/{script}", *argv], cwd=ROOT, env=env, capture_output=True, text=True)
  assert p.returncode == 2 and says in p.stderr and not runs.exists()


def test_the_campaign_script_is_one_campaign_over_its_tasks_and_seeds(parsed):
  """`launch/campaign.sh TASKS SEEDS PRESET METHODS [FLAGS]` starts one `campaign` over every task and
  seed, its flags after them passed on (`--executor=slurm`)."""
  ((argv, configs),) = parsed("campaign.sh", "lift can", "0 1", "cpu", "dp,soe", "--executor=slurm")
  flags = dict(a.split("=", 1) for a in argv[3:])
  assert (flags["--config"], flags["--tasks"], flags["--seeds"]) == ("configs/lift.py:cpu", "lift,can", "0,1")
  assert (
    flags["--executor"] == "slurm" and flags["--results"] == "results/campaign-cpu" and sorted(configs) == ["dp", "soe"]
  )
  grid = campaign_lib.grid(flags["--config"], {}, ["lift", "can"], ["0", "1"])
  assert [(spec, o["seed"]) for spec, o in grid] == [("configs/lift.py:cpu", 0), ("configs/lift.py:cpu", 1),
                                                     ("configs/can.py:cpu", 0), ("configs/can.py:cpu", 1)]  # fmt: skip

"""The comparison of methods as a measurement: the control and the oracle arm, evaluation paired across
rounds and methods, the aggregate over seeds against the control, and a campaign's exported files."""

import json
import os

import numpy as np
import pytest

# (submitit's log handlers take the streams of when it is imported: these, not a test's captured ones)
import soe_jax.analysis.slurm  # noqa: F401
from configs import lift as lift_config
from soe_jax.analysis import aggregate, campaign, report, results
from soe_jax.experiment import phases
from soe_jax.experiment.rundir import RunDir
from soe_jax.runtime.errors import UserError
from soe_jax.train import checkpoint
from tests.experiment import toy, toy_config


def test_every_round_and_method_evaluates_same_states_and_keys(toy_run, toy_task):
  """Every round and method is evaluated on the same states with the same keys (the loop's logic: the
  toy task's run)."""
  _, config, workdir = toy_run
  state = checkpoint.load(RunDir(workdir, config).ckpt_dir(0)).state
  outputs = []
  for method, r in (("soe", 0), ("soe", 2), ("dp", 1)):
    c = toy.get_config(f"smoke,{method}")
    exp = phases.Experiment(c, RunDir(workdir, c), progress=False)
    outputs.append(exp.evaluate(state, r))
  assert outputs[0] == outputs[1] == outputs[2]  # outcomes, jerk, lengths: the same episodes
  report.write(workdir)
  saved = json.load(open(os.path.join(workdir, "outcomes.json")))  # and the run recorded them per state
  assert saved["evaluate"]["0"] == outputs[0]["success"] and sorted(saved["evaluate"]) == ["0", "1", "2"]
  assert len(saved["explore"]["1"]) == config.explore.num_start_states * config.explore.tries


@pytest.mark.slow
def test_expert_data_on_square_is_the_demonstrators_plan(tmp_path):
  """Square's oracle data succeed from every kept start state (the re-planning `expert` strategy
  succeeded on none of them: it leaves the nut resting on the peg's top)."""
  import jax

  from configs import square as square_config
  from soe_jax.envs import observations

  config = square_config.get_config("smoke,dp,expert_data")
  config.env.episode_length = config.data.max_length = 400
  config.rounds.update(num_rounds=1, round0_dir=str(tmp_path / "round0"))
  exp = phases.Experiment(config, RunDir.create(str(tmp_path / "run"), config), progress=False)
  keys = jax.random.split(jax.random.PRNGKey(5), 3)
  rec, episodes = exp.expert_episodes(keys, dict(num_episodes=3))
  assert rec["explored_episodes"] == 3 and rec["num_episodes"] == len(episodes) == 3
  assert rec["expert_success_rate"] == 1.0 and all(ep["success"] for ep in episodes)
  for ep, key in zip(episodes, keys):
    start = observations.policy_obs(exp.env.reset(key).obs)
    np.testing.assert_allclose(observations.policy_obs(ep["obs"], xp=np)[0], start, atol=1e-6)


def _fake_run(path, method, seed, before, after, explored=(), jerk=3.0, rounds=1):
  """A finished one-round run directory (`rounds=0`: round 0 alone, `after` unused) with hand-made
  per-state outcomes (`explored`: per start state, its 2 tries)."""
  os.makedirs(path)
  config = lift_config.get_config(f"smoke,{method}").to_dict()
  config.update(seed=seed)
  config["rounds"]["num_rounds"] = rounds
  json.dump(config, open(os.path.join(path, "config.json"), "w"))
  lines = []
  for r, outcomes in ((0, before), (1, after))[: rounds + 1]:
    rate = sum(outcomes) / len(outcomes)
    lines.append(dict(round=r, phase="evaluate", success_rate=rate, num_rollouts=len(outcomes), wilson_low=0.0,
                      wilson_high=1.0, time_total_s=1.0))  # fmt: skip
  if method != "control" and rounds:
    lines.insert(1, dict(round=1, phase="explore", pass_at_k=0.5, k=2, jerk=jerk, rollouts=3, rollouts_mean=1.5,
                         num_episodes=2, kept_length_mean=40.0))  # fmt: skip
  with open(os.path.join(path, "metrics.jsonl"), "w") as f:
    f.writelines(json.dumps(m) + "\n" for m in lines)
  explore = {"1": [t for state in explored for t in state]} if explored else {}
  evaluate = {"0": before, "1": after} if rounds else {"0": before}
  json.dump(dict(evaluate=evaluate, explore=explore), open(os.path.join(path, "outcomes.json"), "w"))


def test_aggregate_pairs_each_method_with_round0_and_its_control(tmp_path):
  """The aggregate pairs each method with its round 0 and with the control of its seed."""
  base = {0: [1, 0, 0, 1], 1: [0, 0, 1, 0]}
  _fake_run(tmp_path / "s0" / "soe", "soe", 0, base[0], [1, 1, 1, 0])
  _fake_run(tmp_path / "s0" / "control", "control", 0, base[0], [1, 0, 0, 0])
  _fake_run(tmp_path / "s1" / "soe", "soe", 1, base[1], [1, 1, 1, 0])
  _fake_run(tmp_path / "s1" / "control", "control", 1, base[1], [0, 0, 1, 1])
  rows = {r["method"]: r for r in aggregate.rows(aggregate.find_runs(str(tmp_path)))}
  soe, control = rows["soe"], rows["control"]
  assert soe["seeds"] == control["seeds"] == 2 and soe["sr_after_episodes"] == 8
  vs0, vsc = soe["comparisons"]["round0"], soe["comparisons"]["control"]
  assert (vs0["gained"], vs0["lost"]) == (4, 1)  # seed 0: +2 -1; seed 1: +2
  assert (vsc["gained"], vsc["lost"]) == (4, 1) and vsc["differences"] == [0.5, 0.25]  # seed 1 lost state 3
  assert vsc["p_value"] == pytest.approx(0.17971, abs=1e-5)  # CMH over (seed, state): chi-square 9 / 5
  assert soe["vs_control"] == "+37.5 ± 17.7 pts, 4 / 1, p=0.18"
  assert control["comparisons"]["control"] is None and control["vs_control"] == "-"
  md, _ = aggregate.aggregate(aggregate.find_runs(str(tmp_path)))
  assert md.splitlines()[-1].startswith("| lift | control |")  # the control's row last
  table = results.table(str(tmp_path)).splitlines()  # the folder's runs -> the paper's columns
  assert table[2] == ("| lift | soe | 2 | 50.0 ± 0.0% | 3.0 ± 0.0 | 3.0 ± 0.0 | 2.0 ± 0.0 (40.0 ± 0.0 steps) | "
                      "37.5 ± 17.7% | 75.0 ± 0.0% (75.0% "
                      "[40.9%, 92.9%], n=8) | +125.0 ± 106.1% | +37.5 ± 17.7 pts, 4 / 1, p=0.18 | "
                      "+37.5 ± 17.7 pts, 4 / 1, p=0.18 |")  # fmt: skip
  assert table[3].startswith("| lift | control | 2 | - | - | - | - | 37.5 ± 17.7% |") and table[3].endswith("| - |")
  # An arm that keeps other episodes (a selection rule, a length cap) is paired with the same control.
  _fake_run(tmp_path / "s0" / "short", "soe,select=shortest_success,length_cap=1.5", 0, base[0], [1, 1, 0, 1])
  short = {r["method"]: r for r in aggregate.rows(aggregate.find_runs(str(tmp_path)))}[
    "soe-select_shortest_success-cap1.5"
  ]
  assert short["comparisons"]["control"]["gained"] == 2 and short["comparisons"]["control"]["lost"] == 0
  # A method without a control of its seed and settings has no such comparison.
  _fake_run(tmp_path / "s2" / "dp", "dp", 2, base[0], base[0])
  assert {r["method"]: r for r in aggregate.rows(aggregate.find_runs(str(tmp_path)))}["dp"]["vs_control"] == "-"


def test_a_round_0_only_campaign_tables_round_0s_success_and_nothing_after(tmp_path):
  """`--config.rounds.num_rounds=0` (a demonstration count's calibration): success before is round 0's,
  over seeds; every column after it a dash, no interval of no episodes."""
  _fake_run(tmp_path / "s0" / "control", "control", 0, [1, 0, 0, 1], None, rounds=0)
  _fake_run(tmp_path / "s1" / "control", "control", 1, [1, 1, 1, 0], None, rounds=0)
  (row,) = aggregate.rows(aggregate.find_runs(str(tmp_path)))
  assert row["per_seed"]["sr_before"] == [0.5, 0.75] and row["sr_after_episodes"] == 0
  md, _ = aggregate.aggregate(aggregate.find_runs(str(tmp_path)))
  assert md.splitlines()[-1].split(" | ")[9:13] == ["0.625 ± 0.18", "-", "0", "-"]
  assert (
    results.table(str(tmp_path)).splitlines()[2].startswith("| lift | control | 2 | - | - | - | - | 62.5 ± 17.7% | - |")
  )


def test_an_arm_under_a_protocol_or_a_style_pairs_with_the_control_under_the_same(tmp_path):
  """`protocol=sime` and `style=varied` arms fit their own round 0, and their control is the one fitted
  on it (not the plain control, which is no one's control but its own arms'); the action range's control
  differs from the plain one in an arm field only and pairs with it as an arm does."""
  base, other = [1, 0, 0, 1], [0, 1, 1, 1]
  _fake_run(tmp_path / "control", "control", 0, base, [1, 0, 0, 0])
  _fake_run(tmp_path / "soe", "soe", 0, base, [1, 1, 0, 0])
  for variant, after in (("protocol=sime", [0, 0, 0, 1]), ("style=varied", [1, 1, 1, 0])):
    _fake_run(tmp_path / f"control-{variant}", f"control,{variant}", 0, other, after)
    _fake_run(tmp_path / f"soe-{variant}", f"soe,{variant}", 0, other, [1, 1, 1, 1])
  _fake_run(tmp_path / "control-range", "control,range=demonstrations", 0, base, [1, 1, 0, 1])
  rows = {r["method"]: r for r in aggregate.rows(aggregate.find_runs(str(tmp_path)))}
  gained = lambda m: (rows[m]["comparisons"]["control"]["gained"], rows[m]["comparisons"]["control"]["lost"])
  assert gained("soe") == (1, 0) and gained("control-range_demonstrations") == (2, 0)
  assert gained("soe-protocol_sime") == (3, 0) and gained("soe-style_varied") == (1, 0)
  assert rows["control-protocol_sime"]["vs_control"] == rows["control-style_varied"]["vs_control"] == "-"
  md, _ = aggregate.aggregate(aggregate.find_runs(str(tmp_path)))
  last = [line.split(" | ")[1] for line in md.splitlines()[-3:]]  # the controls' rows last
  assert sorted(last) == ["control", "control-protocol_sime", "control-style_varied"]


def test_seeds_logged_differently_are_one_arm(tmp_path):
  """How a run is logged (videos, wandb) is not part of the experiment: it does not split an arm."""
  for seed in (0, 1):
    _fake_run(tmp_path / f"s{seed}" / "soe", "soe", seed, [1, 0, 0, 1], [1, 1, 1, 0])
  path = tmp_path / "s1" / "soe" / "config.json"
  config = json.load(open(path))
  config["log"].update(videos=4, wandb=True)
  json.dump(config, open(path, "w"))
  rows = aggregate.rows(aggregate.find_runs(str(tmp_path)))
  assert [(r["method"], r["seeds"]) for r in rows] == [("soe", 2)]


def test_a_campaign_runs_its_methods_and_exports_their_commands(tmp_path):
  """A campaign runs its methods and exports each run with its command."""
  results = tmp_path / "results"
  spec = toy_config.__file__  # the toy task's config file: the campaign's logic on a task that runs in seconds
  with toy.registered():
    md = campaign.campaign(f"{spec}:smoke", {"seed": 3, "rounds.num_rounds": 1}, ["control"],
                           str(tmp_path / "runs"), str(results), progress=False)  # fmt: skip
  out = results / "toy" / "seed3" / "control"
  assert sorted(os.listdir(out)) == ["command.json", "config.json", "metrics.jsonl", "outcomes.json", "report.md"]
  source = json.load(open(out / "command.json"))
  assert source["kind"] == "run" and source["main_command"].startswith(
    f"python -m soe_jax run --config={spec}:smoke,control --config.rounds.num_rounds=1 --config.seed=3 "
  )
  assert "round0_dir=" in source["main_command"]
  assert json.load(open(out / "config.json"))["seed"] == 3
  assert os.path.isdir(tmp_path / "runs" / "toy" / "seed3" / "round0")  # its own round 0
  assert "| toy | control |" in md and (results / "comparison.md").read_text() == md
  with pytest.raises(UserError, match=r"method 'sime\+oops'"):
    campaign.campaign("configs/lift.py:smoke", {}, ["sime+oops"], str(tmp_path / "x"), str(results), False)
  assert not os.path.exists(tmp_path / "x")  # nothing written for a bad method
  # A variant that changes nothing under the config's presets (cpu's KL weight) is no second arm.
  with pytest.raises(UserError, match=r"methods 'soe' and 'soe,beta=1e-05' are the same arm 'soe'"):
    campaign.campaign("configs/lift.py:cpu", {}, ["soe", "soe+beta=1e-05"], str(tmp_path / "x"), str(results), False)
  assert not os.path.exists(tmp_path / "x")


def test_compare_explores_each_method_from_round0(toy_run, toy_task):
  """`compare` explores each method as its preset says, from the run's shared round 0 (the toy task's
  run: the driver's logic)."""
  from soe_jax.analysis import compare
  from soe_jax.runtime import configfile

  root, config, workdir = toy_run
  overrides = {"seed": config.seed, "explore.num_start_states": 2, "explore.tries": 2}
  spec = f"{toy_config.__file__}:smoke"
  configs = {m: configfile.load(spec, m, overrides) for m in ("dp", "soe_steer")}
  assert configs["soe_steer"].explore.strategy.kwargs.num_proposals == 4  # the smoke preset's steering
  rows = compare.compare(configs, str(root / "compare"), progress=False)
  assert [(r["method"], r["strategy"], r["k"], r["episodes"]) for r in rows] == [("dp", "dp", 2, 4),
                                                                              ("soe_steer", "soe_steer", 2, 4)]  # fmt: skip
  saved = json.load(open(os.path.join(root, "compare", "compare.json")))
  base = json.load(open(os.path.join(RunDir(workdir, config).round0, "evaluate.json")))
  assert saved["base"]["success_rate"] == base["success_rate"]  # the fixture's round 0, not a new fit
  assert "| soe_steer |" in open(os.path.join(root, "compare", "compare.md")).read()


def test_a_campaigns_seed_is_the_configs_unless_overridden():
  """A campaign's seed is the config's unless overridden, and is always in its run commands."""
  spec = "configs/lift.py:smoke"
  seed, overrides, configs = campaign.configs(spec, {"rounds.num_rounds": 1}, ["dp", "soe+expert_data"])
  assert seed == 0 and overrides == {"rounds.num_rounds": 1, "seed": 0}  # the config file's seed, named
  assert {presets: c.method for presets, c in configs.items()} == {"dp": "dp", "soe,expert_data": "soe-expert_data"}
  seed, overrides, configs = campaign.configs(spec, {"seed": 4, "log.videos": 0}, ["dp"])
  assert seed == 4 and list(overrides.items()) == [("log.videos", 0), ("seed", 4)] and configs["dp"].seed == 4
  command = campaign.main_command(spec, "dp", overrides, "runs/x/dp", "runs/x/round0")
  assert command == ("python -m soe_jax run --config=configs/lift.py:smoke,dp --config.log.videos=0 --config.seed=4 "
                     "--config.rounds.round0_dir=runs/x/round0 --workdir=runs/x/dp")  # fmt: skip


def test_the_papers_claims_are_tested_on_the_paired_runs(tmp_path):
  """Each claim tested at the seed level: per-seed differences, the interval, both p-values labelled, a verdict."""
  from soe_jax.analysis import claims

  n = 40
  base = [0] * n
  won = lambda k: [1] * k + [0] * (n - k)
  after = {"soe": (30, 28, 32), "sime": (5, 6, 4), "dp": (5, 7, 5), "control": (5, 4, 6)}
  explored = {
    "soe": lambda s: [[1, 0]] * (30 + s) + [[0, 1]] * (10 - s),
    "sime": lambda s: [[0, 1]] * (25 - s) + [[0, 0]] * (15 + s),
    "dp": lambda s: [[0, 0]] * (n - s) + [[0, 1]] * s,
  }
  jerks = {"soe": [3.0, 3.3, 2.9], "sime": [9.0, 12.0, 10.0], "dp": [3.1, 3.0, 3.2]}
  for seed in range(3):
    for method in ("soe", "sime", "dp"):
      _fake_run(tmp_path / f"s{seed}" / method, method, seed, base, won(after[method][seed]), explored[method](seed),
                jerks[method][seed])  # fmt: skip
    _fake_run(tmp_path / f"s{seed}" / "control", "control", seed, base, won(after["control"][seed]))
  rows = aggregate.rows(aggregate.find_runs(str(tmp_path)))
  success, passes, rollouts, jerk = map(str, claims.claims(rows, "lift"))
  title = "SOE raises success (paper, real robot: SOE alone +19.1% to +38.0% relative; DP can degrade)"
  assert success.startswith(f"{title}: reproduced; SOE against the control +62.5 points [")
  assert "(per seed +62.5, +60.0, +65.0; seed-level p = " in success and "; pooled p = " in success
  assert "tested against +0.0 points (+19.1% of round 0's 0.0%)" in success
  assert (
    "DP against the control +1.7 points [-4.6, +7.9] (per seed +0.0, +7.5, -2.5; seed-level p = 0.56, 8 df" in success
  )
  assert passes.startswith("Pass@5 ordered SOE > SIME > DP: reproduced; SOE - SIME +40.0 points [+34.3, +45.7]")
  assert "SIME - DP +57.5 points [+51.8, +63.2] (per seed +62.5, +57.5, +52.5; seed-level p = 9.4e-06, 4 df" in passes
  assert rollouts.startswith("SOE needs the fewest rollouts: reproduced; SOE - dp ")
  assert "fewer on 93 start states, more on 0" in rollouts
  assert jerk.startswith("SIME's jerk far above DP's and SOE's: reproduced; SIME / DP 3.31x [")
  assert "SOE / DP 0.99x [" in jerk and "(t-test over seeds p = 0.8" in jerk
  *_, one_seed = claims.claims(aggregate.rows(aggregate.find_runs(str(tmp_path / "s0"))), "lift")
  assert (
    str(one_seed)
    == "SIME's jerk far above DP's and SOE's: anecdote; SIME / DP 2.90x, SIME / SOE 3.00x, SOE / DP 0.97x."
  )
  first_seed = str(claims.claims(aggregate.rows(aggregate.find_runs(str(tmp_path / "s0"))), "lift")[0])
  assert first_seed.startswith(f"{title}: anecdote; SOE against the control +62.5 points (per seed +62.5)")
  assert "p = " not in first_seed.split(";")[1]  # an anecdote has no p-value
  md = results.table(str(tmp_path))
  assert "- lift: SOE needs the fewest rollouts: reproduced" in md
  # Over several folders: per claim, a line per folder naming its verdict, numbers and seeds.
  summary = results.regenerate(f"<!-- claims: {tmp_path} {tmp_path / 's0'} -->\n<!-- /table -->\n").splitlines()
  assert summary[1] == f"- {title}:"
  assert summary[2].startswith(
    f"  - lift, 3 seeds (`{tmp_path}`): **reproduced**; SOE against the control +62.5 points"
  )
  assert summary[3].startswith(f"  - lift, 1 seed (`{tmp_path / 's0'}`): **anecdote**; SOE against the control")
  assert summary[4] == "- Pass@5 ordered SOE > SIME > DP:"
  families = summary.index(
    "- The moderated test's families of success (every fit of the task in the folder but the oracle arms):"
  )
  assert summary[families + 1].startswith(
    f"  - lift (`{tmp_path}`): 5 fits (control, round 0, dp, sime, soe) on 3 seeds, 8 df"
  )
  # Brief: a line per claim, each verdict naming its tasks and seeds.
  brief = results.regenerate(f"<!-- claims-brief: {tmp_path} {tmp_path / 's0'} -->\n<!-- /table -->\n").splitlines()
  assert brief[1] == f"- {title}: **reproduced** on lift (3 seeds); **anecdote** on lift (1 seed)."
  assert (
    brief[4]
    == "- SIME's jerk far above DP's and SOE's: **reproduced** on lift (3 seeds); **anecdote** on lift (1 seed)."
  )
  assert len(brief) == 1 + 4 + 1


def test_a_kl_arm_pairs_with_the_control_only_where_its_base_path_is_the_controls(tmp_path):
  """beta refits round 0 but not its base path: the arm pairs with the control of the other beta when
  their round-0 evaluations agree state by state, and is refused when they do not."""
  base = [1, 0, 0, 1]
  _fake_run(tmp_path / "s0" / "control", "control", 0, base, [1, 0, 0, 0])
  _fake_run(tmp_path / "s0" / "soe-beta0", "soe,beta=0", 0, base, [1, 1, 0, 1])
  row = {r["method"]: r for r in aggregate.rows(aggregate.find_runs(str(tmp_path)))}["soe-beta0"]
  assert (row["comparisons"]["control"]["gained"], row["comparisons"]["control"]["lost"]) == (2, 0)
  _fake_run(tmp_path / "s1" / "control", "control", 1, base, [1, 0, 0, 0])
  _fake_run(tmp_path / "s1" / "soe-beta0", "soe,beta=0", 1, [0, 0, 0, 1], [1, 1, 0, 1])
  with pytest.raises(UserError, match="keeps the base path, but their round-0 evaluations differ"):
    aggregate.rows(aggregate.find_runs(str(tmp_path)))


def test_a_campaigns_tasks_and_seeds_make_its_grid():
  """`--tasks` names config files beside `--config`'s, with its presets; `--seeds` sets each seed."""
  grid = campaign.grid("configs/lift.py:cpu", {"log.videos": 0}, ["lift", "can"], ["0", "2"])
  assert grid == [("configs/lift.py:cpu", {"log.videos": 0, "seed": 0}), ("configs/lift.py:cpu", {"log.videos": 0, "seed": 2}),
                  ("configs/can.py:cpu", {"log.videos": 0, "seed": 0}), ("configs/can.py:cpu", {"log.videos": 0, "seed": 2})]  # fmt: skip
  assert campaign.grid("configs/lift.py", {"seed": 4}, [], []) == [("configs/lift.py", {"seed": 4})]
  for tasks, seeds, overrides, message in (
    (["lift", "lfit"], [], {}, r"no config file at 'configs/lfit.py'"),
    (["lift", "lift"], [], {}, r"--tasks names a task twice: lift,lift"),
    ([], ["0", "one"], {}, r"--seeds takes integers, got 0,one"),
    ([], ["1", "1"], {}, r"--seeds names a seed twice: 1,1"),
    ([], ["0", "1"], {"seed": 3}, r"give the training seeds once: --seeds=0,1,2 or --config.seed=K, not both"),
  ):
    with pytest.raises(UserError, match=message):
      campaign.grid("configs/lift.py:cpu", overrides, tasks, seeds)


def test_a_campaigns_mistakes_are_one_line_before_anything_is_queued(tmp_path, monkeypatch, capsys):
  """A bad seed, or `--executor=slurm` where SLURM's commands are missing: one `error:` line, nothing
  written."""
  from soe_jax import __main__ as entry

  monkeypatch.setenv("PATH", str(tmp_path))  # (no srun)
  common = ["soe_jax", "campaign", "--config=configs/lift.py:smoke", f"--workdir={tmp_path / 'runs'}",
            f"--results={tmp_path / 'results'}"]  # fmt: skip
  for args, expected in (
    (["--seeds=0,x"], "error: --seeds takes integers, got 0,x"),
    (
      ["--seeds=0", "--executor=slurm"],
      "error: --executor=slurm needs SLURM's commands (srun, sbatch) on this machine",
    ),
  ):
    with pytest.raises(SystemExit) as stopped:
      entry.main(common + args)
    assert stopped.value.code == 2 and capsys.readouterr().err.strip().splitlines() == [expected]
  assert not os.path.exists(tmp_path / "runs") and not os.path.exists(tmp_path / "results")

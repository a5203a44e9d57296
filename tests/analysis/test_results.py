"""Tables from committed result records compare every row with the first on the same states."""

import json
import os
import subprocess
import sys

import pytest

from soe_jax.analysis import results

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _record(success, commit):
  n = len(success)
  ev = dict(success=success, success_rate=sum(success) / n, wilson_low=0.1, wilson_high=0.9, num_rollouts=n)
  fit = dict(time_total_s=10.0, time_compile_s=1.0, final_loss=0.5)
  return dict(kind="round0", commit=commit, inputs="x", fit=fit, evaluate=ev)


def test_table_rows_in_file_order_paired_with_the_first(tmp_path):
  (tmp_path / "01_a.json").write_text(json.dumps(_record([1, 0, 0, 0], "aaa")))
  (tmp_path / "02_b.json").write_text(json.dumps(_record([0, 1, 1, 1], "bbb")))
  rows = results.table(str(tmp_path)).splitlines()[2:]
  assert rows[0].startswith("| 01_a | x | aaa |") and rows[0].endswith("| - |")
  assert "25.0%" in rows[0] and "75.0%" in rows[1] and rows[1].endswith("| 3 / 1 (p=0.62) |")


def test_convergence_records_get_a_row_per_recipe_naming_diffs(tmp_path):
  """Convergence records get a row per recipe, naming what differs from the first."""
  from soe_jax import metrics

  def record(lr, before, after):
    curve = [dict(success_rate=0.5), dict(success_rate=0.6)]
    fit = dict(steps=100, time_steps_s=10.0, time_total_s=12.0, eval_curve=curve)
    ev = lambda s: dict(success_rate=sum(s) / len(s), num_rollouts=len(s), success=s)
    check = dict(metrics.convergence(before, after, [0.5, 0.6]), before=ev(before), after=ev(after))
    return dict(kind="converge", commit="abc", config=dict(fit=dict(lr=lr, num_steps=100)), fit=fit, check=check)

  (tmp_path / "01.json").write_text(json.dumps(record(3e-4, [1, 0, 0, 0], [1, 1, 1, 0])))
  (tmp_path / "02.json").write_text(json.dumps(record(1e-3, [0, 1, 1, 0], [1, 0, 0, 0])))
  rows = results.table(str(tmp_path)).splitlines()[2:]
  assert rows[0].startswith("| 01 | - | abc | 100 | 10 s (12 s) | 50 / 60 | 25.0% -> 75.0% (n=4) | +50.0")
  assert rows[0].endswith("| no | - |") and rows[1].startswith("| 02 | fit.lr=0.001 |")
  assert "-25.0 [" in rows[1] and rows[1].endswith("| +25.0 pts, 2 / 1 (p=1) |")  # its fit against the first's, paired


def test_latent_rows_get_effective_dims_and_paired_exploration(tmp_path):
  """Latent records get their effective dimensions, and exploration paired with the first record's."""

  def record(fraction, snr, success):
    ex = dict(success=success, success_rate=sum(success) / len(success), wilson_low=0.1, wilson_high=0.9,
              num_rollouts=len(success), pass_at_k=0.5, k=2, jerk=3.0)  # fmt: skip
    dims = [i for i in sorted(range(len(snr)), key=lambda i: -snr[i]) if snr[i] > 0]
    config = dict(policy=dict(bypass=dict(batch_fraction=fraction, beta=1e-3)))
    return dict(kind="latent", commit="abc", config=config, latent=dict(snr_db=snr, effective_dims=dims), explore=ex)

  (tmp_path / "01.json").write_text(json.dumps(record(1.0, [3.0, -1.0, 5.0], [1, 1, 0, 0])))
  evaluated = dict(success_rate=0.625, num_rollouts=8)
  second = record(0.25, [-2.0, 1.0, -1.0], [0, 1, 1, 1]) | {"round0": evaluated}
  second["latent"] |= dict(signal_db=[-30.0, -19.0, -1.0], noise_db=[-28.0, -20.0, 0.0])
  (tmp_path / "02.json").write_text(json.dumps(second))
  rows = results.table(str(tmp_path)).splitlines()[2:]
  assert rows[0].startswith("| 01 | - | abc | - | 2 [2, 0] | 5.0 dB | - | 50.0%") and rows[0].endswith("| - |")
  assert rows[1].startswith(
    "| 02 | policy.bypass.batch_fraction=0.25 | abc | 62.5% (n=8) | 1 [1] | 1.0 dB | -20.0 dB | 75.0%"
  )
  assert rows[1].endswith("| 2 / 1 (p=1) |") and len(rows) == 2  # one task, size and seed: no summary


def test_latent_sweeps_get_effective_dims_beside_the_papers(tmp_path):
  """Latent records of tasks, sizes, KL weights and seeds get their effective dimensions beside the paper's."""

  def record(task, d, seed, snr, beta=1e-3, style=None):
    ex = dict(success=[1, 0], success_rate=0.5, wilson_low=0.1, wilson_high=0.9, num_rollouts=2, pass_at_k=0.5, k=2,
              jerk=3.0)  # fmt: skip
    config = dict(env=dict(task=task), seed=seed, policy=dict(bypass=dict(latent_dim=d, batch_fraction=1.0, beta=beta)))
    config["rounds"] = dict(round0_dir=f"/runs/seed{seed}/round0")  # where round 0 lives: no setting
    if style:  # (records from before the demonstration styles have none: scripted)
      config["data"] = dict(demo_style=style)
    dims = [i for i in range(len(snr)) if snr[i] > 0]
    return dict(kind="latent", commit="abc", config=config, latent=dict(snr_db=snr, effective_dims=dims), explore=ex)

  for name, args in {
    "a": ("lift", 16, 0, [1, 1, -1]),
    "b": ("lift", 16, 1, [1, -1, -1]),
    "c": ("can", 32, 0, [1, 2, 3]),
    "d": ("lift", 16, 0, [1, 1, 1], 0.0),  # the KL ablation: its own row, no paper number
    "e": ("lift", 16, 1, [1, 1, 1, 1], 1e-3, "varied"),  # another style: its own row
  }.items():
    (tmp_path / f"{name}.json").write_text(json.dumps(record(*args)))
  latent, summary = (part.splitlines() for part in results.table(str(tmp_path)).split("\n\n"))
  assert [row.endswith("| - |") for row in latent[2:]] == [True, True, True, False, False]  # d and e paired
  assert [row.split(" | ")[1] for row in latent[2:]] == [
    "-",
    "-",
    "env.task=can, policy.bypass.latent_dim=32",
    "policy.bypass.beta=0.0",
    "data.demo_style=varied",
  ]  # (not the seed or round 0's place)
  assert summary[2:] == [
    "| can | 32 | 0.001 | scripted | 1 | seed 0: 3 | 3 | 8 |",
    "| lift | 16 | 0 | scripted | 1 | seed 0: 3 | 3 | - |",
    "| lift | 16 | 0.001 | scripted | 2 | seed 0: 2, seed 1: 1 | 1.5 ± 0.7 | 8 |",
    "| lift | 16 | 0.001 | varied | 1 | seed 1: 4 | 4 | 8 |",
  ]


def test_demonstration_styles_get_a_row_each_with_the_thresholds_they_meet(tmp_path):
  """A task whose equivalents are the nut's turns shows them (the others a dash) and names what it meets."""
  base = dict(success_rate=1.0, arc_left=0.3, arc_right=0.25, straight=0.45, face_0=0.5, face_1=0.5, path_cv=0.1,
              paused=0.2, length_mean=50.0, length_std=5.0)  # fmt: skip
  lift = dict(base, thresholds_met=dict(arc_each_side=True, face_each=True, success=True))
  square = dict(base, carry_left=0.4, carry_right=0.1, turn_short=0.8, turn_long=0.2,
                thresholds_met=dict(arc_each_side=True, turn_each=True, success=True, carry_each_side=False))  # fmt: skip
  for name, task, v in (("a_lift", "lift", lift), ("b_square", "square", square)):
    record = dict(kind="demo_styles", task=task, style="varied", num_episodes=200, variety=v, commit="abc")
    (tmp_path / f"{name}.json").write_text(json.dumps(record))
  rows = results.table(str(tmp_path)).splitlines()
  assert rows[2].split(" | ")[5:8] == ["-", "50.0% / 50.0%", "-"]
  assert rows[3].split(" | ")[5:8] == ["40.0% / 10.0%", "50.0% / 50.0%", "80.0% / 20.0%"]
  assert rows[3].split(" | ")[-2] == "arc_each_side, turn_each, success"


def test_a_two_arm_demonstrator_gets_a_row_per_arm(tmp_path):
  """Transport's arms are measured each on its own: a row each, named after the record and the arm, a
  dash for the faces of an arm whose object has one grasp."""
  arm = dict(success_rate=1.0, arc_left=0.3, arc_right=0.3, straight=0.4, carry_left=0.3, carry_right=0.2,
             path_cv=0.1, paused=1.0, length_mean=400.0, length_std=50.0)  # fmt: skip
  arms = dict(robot0=dict(arm, thresholds_met=dict(arc_each_side=True, success=True, carry_each_side=False)),
              robot1=dict(arm, face_0=0.4, face_1=0.6, thresholds_met=dict(arc_each_side=True, face_each=True)))  # fmt: skip
  variety = dict(arms=arms, success_rate=1.0, thresholds_met={})
  record = dict(kind="demo_styles", task="transport", style="varied", num_episodes=200, variety=variety, commit="c")
  (tmp_path / "transport_varied.json").write_text(json.dumps(record))
  rows = [r.split(" | ") for r in results.table(str(tmp_path)).splitlines()[2:]]
  assert [r[0] for r in rows] == ["| transport_varied robot0", "| transport_varied robot1"]
  assert [r[6] for r in rows] == ["-", "40.0% / 60.0%"] and rows[0][-2] == "arc_each_side, success"


def test_a_record_without_a_kind_is_an_error_naming_its_file(tmp_path):
  (tmp_path / "01_a.json").write_text(json.dumps(_record([1, 0], "aaa")))
  untyped = _record([0, 1], "bbb")
  del untyped["kind"]
  (tmp_path / "02_b.json").write_text(json.dumps(untyped))
  with pytest.raises(ValueError, match=r"02_b\.json states no kind \(known kinds: .*round0"):
    results.table(str(tmp_path))
  (tmp_path / "02_b.json").write_text(json.dumps(dict(untyped, kind="latent")))
  with pytest.raises(ValueError, match="several kinds: latent, round0"):
    results.table(str(tmp_path))
  (tmp_path / "02_b.json").write_text(json.dumps(dict(untyped, kind="nonsense")))
  (tmp_path / "01_a.json").unlink()
  with pytest.raises(
    ValueError, match="unknown record kind 'nonsense'; known record kinds: action_range, calibration, converge"
  ):
    results.table(str(tmp_path))


def test_generated_tables_are_rewritten_between_their_markers(tmp_path, monkeypatch):
  (tmp_path / "study").mkdir()
  (tmp_path / "study" / "01_a.json").write_text(json.dumps(_record([1, 0], "aaa")))
  monkeypatch.chdir(tmp_path)
  text = "intro\n<!-- table: study -->\n| stale |\n<!-- /table -->\nafter\n"
  new = results.regenerate(text)
  assert new.startswith("intro\n<!-- table: study -->\n| record |") and new.endswith("<!-- /table -->\nafter\n")
  assert "| stale |" not in new and "| 01_a | x | aaa |" in new and results.regenerate(new) == new
  with pytest.raises(ValueError, match="has no '<!-- /table -->'"):
    results.regenerate("<!-- table: study -->\n| x |\n")
  with pytest.raises(ValueError, match="before the next table"):  # not swallowing the next table's text
    results.regenerate("<!-- table: study -->\nprose\n<!-- table: study -->\n<!-- /table -->\n")


def test_the_docs_tables_are_what_their_committed_results_give(monkeypatch):
  """Every generated table in the README, RESULTS.md and BENCHMARKS.md is current (`python -m soe_jax
  results --docs`)."""
  monkeypatch.chdir(ROOT)
  for path in results.DOCS:
    text = open(path).read()
    assert "<!-- table: " in text or "<!-- claims" in text
    assert results.regenerate(text) == text, f"{path} is stale: run python -m soe_jax results --docs"


def test_fit_step_records_get_a_row_per_setting(tmp_path):
  """`bench fit --out` records: a row each, naming the fields in which its config differs from the first's."""
  from configs import lift

  for name, size in (("01_a", 84), ("02_b", 64)):
    config = lift.get_config("cpu,image").to_dict()
    config["env"]["image_size"] = size
    step = dict(params=3_204_403, batch_size=64, ms_per_step=196.0 if size == 84 else 120.0, samples_per_s=320.0)
    (tmp_path / f"{name}.json").write_text(
      json.dumps(dict(kind="fit_step", commit="abc", config=config, fit_step=step))
    )
  rows = results.table(str(tmp_path)).splitlines()[2:]
  assert rows == [
    "| 01_a | - | abc | 3.20M | 64 | 196 ms | 320 |",
    "| 02_b | env.image_size=64 | abc | 3.20M | 64 | 120 ms | 320 |",
  ]


def test_the_docs_figures_plot_what_their_committed_results_give(monkeypatch):
  """Each figure of the claims that the documents name is drawn from its plotted data, committed beside
  it; recomputed from the records, that data is unchanged (the pixels are not compared)."""
  from soe_jax.analysis import figures

  monkeypatch.chdir(ROOT)
  found = [m for path in results.DOCS for m in results.figure_markers(open(path).read())]
  assert {kind for kind, _, _ in found} >= {"forest", "kept", "rounds"}
  for kind, args, path in found:
    assert os.path.exists(path), f"{path} is missing: run python -m soe_jax results --docs"
    committed = json.load(open(figures.data_path(path)))
    recomputed = json.loads(json.dumps(figures.KINDS[kind][0](args)))
    assert recomputed == committed, f"{path}'s data is stale: run python -m soe_jax results --docs"


def test_no_statement_beyond_its_records_remains():
  """Statements a reading of the records refuted stay out of the documents (lines joined, whitespace
  ignored): the steering preset's cap is not the latent's effective dimensions; soe_steer steers every
  fourth decision; +62% is SOE with steering."""
  import re

  for path in ("README.md", "RESULTS.md", "docs/guide.md"):
    text = " ".join(open(os.path.join(ROOT, path)).read().split())
    assert not re.search(r"\b2 effective dimensions", text), path
    assert not re.search(r"at each decision", text), path
    assert not re.search(r"SOE[^.]{0,40}\+19% to \+62%", text), path
    assert not re.search(r"not what limits the round", text), path
    assert not re.search(r"Human-like demonstrations", text), path


def test_a_campaign_of_controls_alone_gets_its_table_and_no_empty_claims(monkeypatch):
  """A campaign that ran only a control (the demonstration-count calibration) tests no claim of the
  paper: its table ends at its last row, without the blank line of an empty claims list."""
  monkeypatch.chdir(ROOT)
  md = results.table("results/protocol-count/sime-n5")
  assert md.count("| lift | control-protocol_sime |") == 1 and md.endswith(" |\n")


def test_the_results_command_prints_a_table_or_refuses_a_folder(tmp_path):
  """`python -m soe_jax results` prints a folder's table, and refuses a folder without records."""
  (tmp_path / "study").mkdir()
  (tmp_path / "study" / "01_a.json").write_text(json.dumps(_record([1, 0], "aaa")))
  command = [sys.executable, "-m", "soe_jax", "results"]
  p = subprocess.run([*command, str(tmp_path / "study")], capture_output=True, text=True)
  assert p.returncode == 0 and p.stdout == results.table(str(tmp_path / "study"))
  p = subprocess.run([*command, str(tmp_path)], capture_output=True, text=True)
  assert (
    p.returncode == 2
    and p.stdout == ""
    and p.stderr == f"error: no result records (*.json) or exported runs in {str(tmp_path)!r}\n"
  )

"""Several rounds as the paper's simulation figure: success per round over seeds, each round paired with
the one before, the claim that only SOE improves monotonically, and the figure drawn from the runs."""

import json
import os

import pytest

from configs import lift as lift_config
from soe_jax.analysis import aggregate, over_rounds, results


def _fake_run(path, method, seed, evaluated, passes=None):
  """A finished run of len(evaluated) - 1 rounds with hand-made per-state outcomes per round."""
  os.makedirs(path)
  config = lift_config.get_config(f"smoke,{method}").to_dict()
  config.update(seed=seed)
  config["rounds"]["num_rounds"] = len(evaluated) - 1
  json.dump(config, open(os.path.join(path, "config.json"), "w"))
  lines = []
  for r, outcomes in enumerate(evaluated):
    if r > 0 and method != "control":
      lines.append(dict(round=r, phase="explore", pass_at_k=passes[r - 1], k=5, jerk=3.0, rollouts=10 * r,
                        rollouts_mean=1.0, num_episodes=2))  # fmt: skip
    lines.append(dict(round=r, phase="evaluate", success_rate=sum(outcomes) / len(outcomes),
                      num_rollouts=len(outcomes), wilson_low=0.0, wilson_high=1.0, time_total_s=1.0))  # fmt: skip
  with open(os.path.join(path, "metrics.jsonl"), "w") as f:
    f.writelines(json.dumps(m) + "\n" for m in lines)
  explored = {str(r): [1, 0, 0, 0, 0] * 4 for r in range(1, len(evaluated))} if method != "control" else {}
  outcomes = dict(evaluate={str(r): o for r, o in enumerate(evaluated)}, explore=explored)
  json.dump(outcomes, open(os.path.join(path, "outcomes.json"), "w"))


def _runs(tmp_path):
  rising = [[1] * 4 + [0] * 36, [1] * 14 + [0] * 26, [1] * 24 + [0] * 16, [1] * 34 + [0] * 6]  # +25 pts a round
  dipping = [[1] * 20 + [0] * 20, [1] * 10 + [0] * 30, [1] * 30 + [0] * 10, [1] * 30 + [0] * 10]
  flat = [[1] * 20 + [0] * 20] * 4
  for seed in range(3):
    _fake_run(tmp_path / f"s{seed}" / "soe", "soe", seed, rising, passes=[0.5, 0.6, 0.7])
    _fake_run(tmp_path / f"s{seed}" / "dp", "dp", seed, dipping, passes=[0.4, 0.4, 0.4])
    _fake_run(tmp_path / f"s{seed}" / "control", "control", seed, flat)
  return aggregate.rows(aggregate.find_runs(str(tmp_path)))


def test_rounds_are_paired_and_only_soe_improves_monotonically(tmp_path):
  """Each round is paired with the round before, and only SOE improves monotonically."""
  rows = {r["method"]: r for r in _runs(tmp_path)}
  soe, dp = rows["soe"], rows["dp"]
  assert over_rounds.rounds_of(soe) == [0, 1, 2, 3]
  steps = over_rounds.steps(soe)
  assert [s["round"] for s in steps] == [1, 2, 3] and all(s["gained"] == 30 and s["lost"] == 0 for s in steps)
  assert [s["difference_mean"] for s in over_rounds.steps(dp)] == pytest.approx([-0.25, 0.5, 0.0])
  tests = over_rounds.step_tests(list(rows.values()))
  assert [t.d for t in tests["soe"]] == [pytest.approx((0.25, 0.25, 0.25))] * 3 and tests["soe"][
    0
  ].df == 2 * 11  # 12 fits: each method its own round 0
  assert over_rounds.improves_every_round(tests["soe"]) and not over_rounds.improves_every_round(tests["dp"])
  assert not over_rounds.improves_every_round(tests["control"])  # no change is no improvement
  claim = str(over_rounds.claim(list(rows.values()), "lift"))
  assert claim.startswith("Only SOE improves monotonically over rounds: reproduced; against dp: soe 10.0")
  assert (
    "soe 10.0 -> 35.0 -> 60.0 -> 85.0% (improves every round: round 1 +25.0 points" in claim
    and "dp 50.0 -> 25.0" in claim
  )


def test_the_rounds_table_and_figure_come_from_the_runs(tmp_path):
  rows = _runs(tmp_path)
  table = results.table(str(tmp_path))
  lines = [line for line in table.splitlines() if line.startswith("| lift | soe | 3 | 10.0")]
  assert lines == ["| lift | soe | 3 | 10.0 ± 0.0 | 35.0 ± 0.0 | 60.0 ± 0.0 | 85.0 ± 0.0 | +25.0 pts, p=4.3e-08; "
                   "+25.0 pts, p=4.3e-08; +25.0 pts, p=4.3e-08 | 50 ± 0 / 60 ± 0 / 70 ± 0 | 10 ± 0 / 20 ± 0 / 30 ± 0 |"]  # fmt: skip
  assert "| lift | control | 3 | 50.0 ± 0.0 |" in table and "- lift: Only SOE improves monotonically" in table
  summary = results.claims_summary([str(tmp_path)]).splitlines()  # rounds answer their claim alone
  assert summary[0] == "- Only SOE improves monotonically over rounds:" and len(summary) == 2
  assert summary[1].startswith(f"  - lift, 3 seeds (`{tmp_path}`): **reproduced**; against dp: soe 10.0 -> 35.0")
  path = tmp_path / "rounds.png"
  over_rounds.figure(rows, str(path))
  assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000
  docs = f"<!-- figure: {tmp_path} {tmp_path / 'drawn.png'} -->\n"
  assert results.figures(docs) == [str(tmp_path / "drawn.png")] and (tmp_path / "drawn.png").exists()
  with pytest.raises(FileNotFoundError, match="no exported runs"):
    results.figures(f"<!-- figure: {tmp_path / 'none'} x.png -->\n")

"""`table1` through its command line on constructed recordings: the exploration table per mode and the
success before and after a re-fit, and Table I for three methods sharing one evaluation before, each
number against a hand computation."""

import json

import numpy as np
import pytest

from soe_jax import __main__ as entry
from soe_jax.data import lerobot
from soe_jax.serve.modes import MODES

FPS = 10


def _episode(success: bool, mode: str, state: int, c: float = 1.0, length: int = 6, fps: int = FPS) -> dict:
  """An episode whose hand follows x = c t^3 (t in seconds): its third difference over dt^3 is 6c at
  every step, so its jerk is 6c."""
  t = np.arange(length) / fps
  actions = np.zeros((length, 10), np.float32)
  actions[:, 0] = c * t**3
  columns = {"mode": np.full(length, MODES.index(mode), np.int64), "start_state": np.full(length, state, np.int64)}
  obs = {"observation.state": np.zeros((length, 3), np.float32)}
  return dict(obs=obs, actions=actions, success=success, columns=columns)


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
  root = tmp_path_factory.mktemp("table1")
  # Exploration, k = 2. soe: state 0 fails then succeeds, state 1 fails twice, state 2 has one try
  # (a success, left out of Pass@k); base: state 0 succeeds twice.
  explore = [_episode(False, "soe", 0, 1.0), _episode(True, "soe", 0, 2.0), _episode(False, "soe", 1, 1.0),
             _episode(False, "soe", 1, 2.0), _episode(True, "soe", 2, 4.0),
             _episode(True, "base", 0, 1.0), _episode(True, "base", 0, 1.0)]  # fmt: skip
  # Evaluations on states 0-3, one try each: before F T F F, after T T F T (2 up, 0 down).
  before = [_episode(s, "base", i) for i, s in enumerate([False, True, False, False])]
  after = [_episode(s, "base", i) for i, s in enumerate([True, True, False, True])]
  paths = {}
  for name, eps in [("rec", explore), ("eval0", before), ("eval1", after)]:
    paths[name] = str(root / name)
    lerobot.write_dataset(paths[name], eps, fps=FPS)
  return paths


def test_table1_with_both_evaluations_matches_a_hand_computation(recordings, tmp_path, capsys):
  out = tmp_path / "table1.json"
  entry.main(["soe_jax", "table1", recordings["rec"], f"--before={recordings['eval0']}",
              f"--after={recordings['eval1']}", "--k=2", f"--out={out}"])  # fmt: skip
  printed = capsys.readouterr().out
  t = json.load(open(out))

  soe, base = t["explore"]["modes"]["soe"], t["explore"]["modes"]["base"]
  assert (soe["episodes"], soe["successes"], soe["start_states"], soe["states_with_k_tries"]) == (5, 2, 3, 2)
  assert soe["success_rate"] == pytest.approx(0.4)
  assert soe["pass_at_k"] == 0.5 and soe["rollouts"] == 4 and soe["rollouts_mean"] == 2.0  # 2 + 2 tries
  jerks = 6 * np.array([1.0, 2.0, 1.0, 2.0, 4.0])  # 6c per episode
  assert soe["jerk_mean"] == pytest.approx(jerks.mean(), rel=1e-3)
  assert soe["jerk_sd"] == pytest.approx(jerks.std(ddof=1), rel=1e-3)
  assert (base["episodes"], base["successes"], base["pass_at_k"], base["rollouts"]) == (2, 2, 1.0, 1)
  assert base["jerk_mean"] == pytest.approx(6.0, rel=1e-3) and base["jerk_sd"] == pytest.approx(0.0, abs=1e-3)

  ba = t["before_after"]
  assert ba["before_dataset"] == recordings["eval0"] and ba["after_dataset"] == recordings["eval1"]
  assert (ba["before"]["rate"], ba["before"]["num_episodes"]) == (0.25, 4)
  assert (ba["after"]["rate"], ba["after"]["num_episodes"]) == (0.75, 4)
  # Wilson's 95% interval for 1 of 4: 0.0456 to 0.6994 (and 3 of 4 its mirror).
  assert ba["before"]["wilson_low"] == pytest.approx(0.0456, abs=1e-4)
  assert ba["before"]["wilson_high"] == pytest.approx(0.6994, abs=1e-4)
  assert ba["after"]["wilson_low"] == pytest.approx(1 - 0.6994, abs=1e-4)
  assert ba["difference"] == 0.5 and ba["relative"] == pytest.approx(2.0)
  se = np.sqrt(2 * 0.75 * 0.25 / 4)
  assert ba["difference_95"] == pytest.approx([0.5 - 1.96 * se, 0.5 + 1.96 * se])
  # Fisher's exact test on [[3, 1], [1, 3]]: the tables as or less likely than the observed one,
  # (C(4,0)^2 + C(4,1)^2 + C(4,3)^2 + C(4,4)^2) / C(8,4) = 34 / 70.
  assert ba["fisher_p"] == pytest.approx(34 / 70)
  # Paired by state: 2 up, 0 down of 4; the two-sided sign test 2 * (1/2)^2.
  assert ba["paired"] == dict(states=4, up=2, down=0, sign_test_p=0.5)

  assert "| soe | 5 | 40.0% [" in printed and "| 50.0% [" in printed
  assert "Before / after the re-fit: 25.0% of 4 -> 75.0% of 4 (+50.0%" in printed
  assert "relative +200%, Fisher p = 0.486" in printed
  assert "Paired by start state: 2 up, 0 down of 4 (sign test p = 0.5)" in printed


@pytest.fixture(scope="module")
def three_methods(tmp_path_factory):
  """dp, sime and soe: each an exploration recording (k = 2, in its own mode) and an evaluation after
  its re-fit, on start states 0-3 with one try each, beside one evaluation before. At 8 Hz, so that
  t^3 and dt^3 are exact in binary and each jerk is exactly 6c."""
  root = tmp_path_factory.mktemp("table1_methods")
  ep = lambda success, mode, state, c=1.0: _episode(success, mode, state, c, fps=8)
  tries = lambda mode, outcomes, cs: [ep(s, mode, state, c) for (state, s), c in zip(outcomes, cs)]
  sets = {
    "before": [ep(s, "base", i) for i, s in enumerate([False, True, False, False])],
    # dp explores state 0: F F, state 1: T F; sime state 0: F T, state 1: F F; soe state 0: T T,
    # state 1: F T, state 2: T (one try, left out of Pass@2).
    "dp_explore": tries("base", [(0, False), (0, False), (1, True), (1, False)], [1.0] * 4),
    "sime_explore": tries("sime", [(0, False), (0, True), (1, False), (1, False)], [1.0, 1.0, 2.0, 2.0]),
    "soe_explore": tries("soe", [(0, True), (0, True), (1, False), (1, True), (2, True)], [2.0] * 5),
    "dp_after": [ep(s, "base", i) for i, s in enumerate([False, False, True, False])],
    "sime_after": [ep(s, "base", i) for i, s in enumerate([True, True, False, False])],
    "soe_after": [ep(s, "base", i) for i, s in enumerate([True, True, True, True])],
  }
  paths = {}
  for name, eps in sets.items():
    paths[name] = str(root / name)
    lerobot.write_dataset(paths[name], eps, fps=8)
  return paths


def test_table1_for_three_methods_matches_a_hand_computation(three_methods, tmp_path, capsys):
  p = three_methods
  out = tmp_path / "table1.json"
  entry.main(["soe_jax", "table1", f"--before={p['before']}", f"--method=dp={p['dp_explore']}:{p['dp_after']}",
              f"--method=sime={p['sime_explore']}:{p['sime_after']}",
              f"--method=soe={p['soe_explore']}:{p['soe_after']}", "--k=2", f"--out={out}"])  # fmt: skip
  printed = capsys.readouterr().out
  # By hand. Wilson's 95% intervals: 1 of 4 [4.6%, 69.9%], 2 of 4 [15.0%, 85.0%], 4 of 4 [51.0%, 100%],
  # 4 of 5 [37.6%, 96.4%], 1 of 2 [9.5%, 90.5%], 2 of 2 [34.2%, 100%]. Rollouts to the first success,
  # 2 when none: dp 2 + 1, sime 2 + 2, soe 1 + 2. Jerk 6c: dp 6, 6, 6, 6; sime 6, 6, 12, 12 (sd
  # sqrt(12) = 3.46); soe 12 each. After against before (1 of 4): the difference 0 / 0.25 / 0.75 with
  # 1.96 sqrt(a(1-a)/4 + b(1-b)/4) either side (0.600, 0.648, 0.424); Fisher's exact p, of the
  # hypergeometric tables (3, 5 or 5 successes in 8, 4 drawn) as or less likely than the observed: dp
  # and sime 1, soe (5 + 5) / 70 = 0.143. Paired by state against before F T F F: dp F F T F one up
  # (state 2) one down (state 1), p 1; sime T T F F one up, p 1; soe T T T T three up, p 2 / 8.
  expected = f"""Before the re-fit ({p["before"]}): 25.0% [4.6%, 69.9%] of 4

| method | explored | success [95% CI] | Pass@2 [95% CI] | rollouts (states with 2 tries) | jerk (8 Hz) \
| success after [95% CI] | change [95% CI] | relative | Fisher p | vs before, paired by state |
|---|---|---|---|---|---|---|---|---|---|---|
| dp | 4 | 25.0% [4.6%, 69.9%] | 50.0% [9.5%, 90.5%] | 3 (2) | 6 ± 0 | 25.0% [4.6%, 69.9%] of 4 \
| +0.0% [-60.0%, +60.0%] | +0% | 1 | 1 up, 1 down of 4 (sign test p = 1) |
| sime | 4 | 25.0% [4.6%, 69.9%] | 50.0% [9.5%, 90.5%] | 4 (2) | 9 ± 3.5 | 50.0% [15.0%, 85.0%] of 4 \
| +25.0% [-39.8%, +89.8%] | +100% | 1 | 1 up, 0 down of 4 (sign test p = 1) |
| soe | 5 | 80.0% [37.6%, 96.4%] | 100.0% [34.2%, 100.0%] | 3 (2) | 12 ± 0 | 100.0% [51.0%, 100.0%] of 4 \
| +75.0% [+32.6%, +117.4%] | +300% | 0.143 | 3 up, 0 down of 4 (sign test p = 0.25) |

Between methods, paired by start state (the states both name; each state's success rate):
- after the re-fit, sime against dp: 2 up, 1 down of 4 (sign test p = 1)
- exploration, sime against dp: 1 up, 1 down of 2 (sign test p = 1)
- after the re-fit, soe against dp: 3 up, 0 down of 4 (sign test p = 0.25)
- exploration, soe against dp: 1 up, 0 down of 2 (sign test p = 1)
- after the re-fit, soe against sime: 2 up, 0 down of 4 (sign test p = 0.5)
- exploration, soe against sime: 2 up, 0 down of 2 (sign test p = 0.5)
-> {out}
"""  # (a backslash at a line's end joins it to the next)
  assert printed == expected

  t = json.load(open(out))
  assert t["before"]["dataset"] == p["before"] and (t["before"]["rate"], t["before"]["num_episodes"]) == (0.25, 4)
  assert list(t["methods"]) == ["dp", "sime", "soe"]
  soe = t["methods"]["soe"]
  assert soe["explore"]["modes"] == {"soe": 5} and soe["explore"]["dataset"] == p["soe_explore"]
  assert (soe["explore"]["episodes"], soe["explore"]["successes"], soe["explore"]["start_states"]) == (5, 4, 3)
  assert soe["after"]["dataset"] == p["soe_after"] and soe["after"]["rate"] == 1.0
  assert soe["vs_before"]["difference"] == 0.75 and soe["vs_before"]["relative"] == pytest.approx(3.0)
  assert soe["vs_before"]["fisher_p"] == pytest.approx(10 / 70)
  assert t["methods"]["sime"]["explore"]["jerk_sd"] == pytest.approx(np.sqrt(12))
  assert [(b["a"], b["b"]) for b in t["between"]] == [("sime", "dp"), ("soe", "dp"), ("soe", "sime")]


def test_table1_methods_refuses_a_malformed_method(three_methods, capsys):
  for bad in ["soe", "soe=:", f"soe={three_methods['soe_explore']}", "=a:b"]:
    with pytest.raises(SystemExit) as e:
      entry.main(["soe_jax", "table1", f"--method={bad}"])
    assert e.value.code == 2
    assert "NAME=EXPLORE:AFTER" in capsys.readouterr().err
  with pytest.raises(SystemExit):
    entry.main(["soe_jax", "table1", three_methods["soe_explore"], f"--method=soe={three_methods['soe_explore']}:"])
  assert "give no RECORDED or --after" in capsys.readouterr().err

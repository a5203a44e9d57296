"""`table1` through its command line on constructed recordings: the exploration table per mode and the
success before and after a re-fit, each number against a hand computation."""

import json

import numpy as np
import pytest

from soe_jax import __main__ as entry
from soe_jax.data import lerobot
from soe_jax.serve.modes import MODES

FPS = 10


def _episode(success: bool, mode: str, state: int, c: float = 1.0, length: int = 6) -> dict:
  """An episode whose hand follows x = c t^3 (t in seconds): its third difference over dt^3 is 6c at
  every step, so its jerk is 6c."""
  t = np.arange(length) / FPS
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

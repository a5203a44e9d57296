"""The run's console progress: round r of R, elapsed time, and the time left at the measured pace."""

from soe_jax import runlog


def test_round_clock_estimates_the_rounds_left_from_the_rounds_run(capsys, monkeypatch):
  now = iter([0.0, 0.0, 600.0, 700.0, 820.0])  # start; round 0 at 0 s, 1 at 600 s, 2 at 700 s, 3 at 820 s
  monkeypatch.setattr(runlog.time, "perf_counter", lambda: next(now))
  clock = runlog.RoundClock(3)
  for r in range(4):
    clock.begin(r)
  lines = capsys.readouterr().out.splitlines()
  assert lines[:2] == ["== round 0 of 3 (elapsed 0m00s)", "== round 1 of 3 (elapsed 10m00s)"]
  assert lines[2] == "== round 2 of 3 (elapsed 11m40s, about 3m20s left)"  # round 1 took 100 s; 2 rounds left
  assert lines[3] == "== round 3 of 3 (elapsed 13m40s, about 1m50s left)"  # mean of 100 s and 120 s

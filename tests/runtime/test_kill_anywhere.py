"""Kill it anywhere: a smoke run and a smoke campaign SIGKILLed at their write sites' kill points
(`runtime.faults`) and at random times, then run again with the same command, finish with what an
uninterrupted run leaves (`kill_anywhere.py`).

The fast test kills one run at one write of each kind in turn (an atomic record, a replaced directory, an
orbax save, an appended line, an HDF5 file); the slow sweeps kill every site at every point (before,
during, after; the first and the last time it is reached), one kill per resumed run, and at random."""

import collections
import random

import pytest

from soe_jax.runtime import faults
from tests.runtime import kill_anywhere as ka

# One site of each kind of write, in the order a run first reaches them.
ONE_PER_KIND = ("partial_fit", "checkpoint", "phase_record", "metrics_line", "episodes")


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
  """`reference(job)` -> (its kill points, what it left, its directory) when run uninterrupted (once)."""
  done = {}

  def get(job: str):
    if job not in done:
      base = tmp_path_factory.mktemp(f"reference-{job}")
      done[job] = ka.trace(job, base), ka.left(job, base), base
    return done[job]

  return get


def _sweep(points: list[ka.Kill]) -> list[ka.Kill]:
  """Each (site, when)'s first and last kill point."""
  last = {}
  for p in points:
    last[p.site, p.when] = p
  return sorted({ka.Kill(s, w, 1) for s, w in last} | set(last.values()), key=points.index)


@pytest.mark.parametrize("job", [ka.JOBS[0], pytest.param(ka.JOBS[1], marks=pytest.mark.slow)])
def test_every_file_a_job_leaves_has_a_write_site_with_every_kill_point(reference, job):
  """A write without a site (a file no site's globs claim), or a site a job never reaches before, during
  and after its write, fails here: the sweeps would not kill there."""
  points, _, base = reference(job)
  assert ka.unclaimed_files(base) == []
  reached = collections.defaultdict(set)
  for p in points:
    reached[p.site].add(p.when)
  # (The toy task draws no videos, which need a MuJoCo scene: `videos` is killed nowhere here, and its
  # writer is the atomic rename tested in tests/experiment/test_video.py.)
  expected = set(faults.SITES) - {"videos"} - (set() if job == "campaign" else {"results_export", "comparison"})
  assert {s for s, whens in reached.items() if whens == set(faults.WHEN)} == expected


@pytest.mark.slow
def test_a_run_killed_at_each_kind_of_write_finishes_as_if_never_killed(reference, tmp_path):
  points, expected, _ = reference("run")
  kills = [ka.Kill(site, "during") for site in ONE_PER_KIND]
  assert all(k in points for k in kills)
  warnings = ka.interrupted("run", tmp_path, kills)
  assert ka.differences(ka.left("run", tmp_path), expected) == []
  assert any("torn last line" in w for w in warnings)  # the metrics line cut in half was repaired
  assert ka.unclaimed_files(tmp_path) == []  # the killed writes' temporary files are gone


@pytest.mark.slow
@pytest.mark.parametrize("job", ka.JOBS)
def test_killed_at_every_kill_point_each_job_finishes_as_if_never_killed(reference, tmp_path, job):
  points, expected, _ = reference(job)
  sweep = _sweep(points)
  found = {}
  for i, kill in enumerate(sweep):
    base = tmp_path / str(i)
    ka.interrupted(job, base, [kill])
    if diff := ka.differences(ka.left(job, base), expected):
      found[str(kill)] = diff
  print(f"{job}: {len({(k.site, k.when) for k in sweep})} (site, when) pairs, {len(sweep)} kill points, "
        f"{len(sweep) - len(found)} recovered")  # fmt: skip
  assert found == {}


@pytest.mark.slow
@pytest.mark.parametrize("job", ka.JOBS)
def test_killed_at_random_times_each_job_finishes_as_if_never_killed(reference, tmp_path, job):
  rng = random.Random(0)
  for i in range(3):
    base = tmp_path / str(i)
    ka.killed_at_random(job, base, sorted(rng.uniform(2.0, 12.0) for _ in range(3)))
    assert ka.differences(ka.left(job, base), reference(job)[1]) == [], i

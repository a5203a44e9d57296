"""Named durable writes, and the switch that kills the process at one of them.

Every file a resumed run or campaign reads back, or leaves as its result, is written at a *site*
(`SITES`: its name, the files it writes, what they are). A writer marks its write with

  with faults.site("phase_record"):
    ...                  # write to a temporary name
    faults.during()      # the new content written, not yet in place (or half a line appended)
    ...                  # rename into place

A site is also where the processes of a multi-host run meet, before the write and once it is done
(`hosts`): every process decides from the same files.

`during()` goes where a kill hurts most: before an atomic write's rename, in the middle of an appended
line, inside an orbax save before it finalises. Normally these marks do nothing. Two environment
variables turn them on, for the kill-anywhere tests (`tests/runtime/test_kill_anywhere.py`):

  SOE_JAX_KILL_AT=SITE:WHEN[:N]  SIGKILL this process the N-th time (default 1) it reaches WHEN (before,
                                 during, after) of SITE: no handler runs, nothing is flushed
  SOE_JAX_SITES_LOG=PATH         append "SITE WHEN" to PATH at each point reached (the kill points a run
                                 offers)
"""

from __future__ import annotations

import collections
import contextlib
import os
import signal
from collections.abc import Iterator

from soe_jax.runtime import hosts

WHEN = ("before", "during", "after")

# name -> (the files it writes, as globs under a run's, a shared round 0's or a campaign's results
# directory; what they are). A finished run's files all match a site's globs (the kill-anywhere test
# checks it), so a new write without a site fails that test.
SITES = {
  "run_config": (("config.json",), "a run's config, written when it starts"),
  "demonstrations": (("demos.hdf5",), "round 0's demonstrations"),
  "partial_fit": (("rounds/*/fit_partial/**", "fit_partial/**"), "a fit in progress (orbax, every save)"),
  "checkpoint": (("rounds/*/ckpt/**", "ckpt/**"), "a round's policy after its fit"),
  "episodes": (("data/round_*.hdf5", "rounds/*/*_episodes.hdf5", "*_episodes.hdf5"), "episodes kept or shown"),
  "phase_record": (("rounds/*/*.json", "fit.json", "evaluate.json"), "a finished phase's record"),
  "metrics_line": (("metrics.jsonl", "tb/*"), "a phase's line in metrics.jsonl and TensorBoard"),
  "report": (("report.md", "outcomes.json", "*.png"), "a finished run's report"),
  "videos": (("videos/*.mp4",), "a round's stored episodes drawn (`log.videos`)"),
  "results_export": (("*/seed*/*/*",), "a campaign's copy of a finished run's small files"),
  "comparison": (("comparison.md", "comparison.csv"), "a campaign's table over its results"),
}
# Files that are no site's: a lock (`runtime.locking`, held by a descriptor, not by its content).
NOT_WRITES = (".lock",)

KILL_ENV = "SOE_JAX_KILL_AT"
LOG_ENV = "SOE_JAX_SITES_LOG"

_active: list[str] = []
_reached: collections.Counter = collections.Counter()


def _parse(spec: str) -> tuple[str, str, int]:
  name, when, *n = spec.split(":")
  if name not in SITES or when not in WHEN or len(n) > 1:
    raise ValueError(f"{KILL_ENV}={spec!r}: expected SITE:WHEN[:N], SITE one of {sorted(SITES)}, WHEN one of {WHEN}")
  return name, when, int(n[0]) if n else 1


def point(name: str, when: str) -> None:
  """Reached `when` of site `name`: logged, and the process killed if the switch says so."""
  if log := os.environ.get(LOG_ENV):
    with open(log, "a") as f:
      f.write(f"{name} {when}\n")
  if spec := os.environ.get(KILL_ENV):
    _reached[name, when] += 1
    if (name, when, _reached[name, when]) == _parse(spec):
      os.kill(os.getpid(), signal.SIGKILL)


@contextlib.contextmanager
def site(name: str) -> Iterator[None]:
  """The write inside is site `name`'s (one of `SITES`)."""
  if name not in SITES:
    raise KeyError(f"unknown write site {name!r}; the sites: {sorted(SITES)}")
  # Several hosts: all meet before process 0 writes, so none can read the new file before deciding as
  # the others did (whether a phase is done, a config saved), and again after, so all read it next.
  hosts.barrier(f"write {name}")
  point(name, "before")
  _active.append(name)
  try:
    yield
  finally:
    _active.pop()
  point(name, "after")
  hosts.barrier(f"wrote {name}")


def during() -> None:
  """The middle of the write of the innermost active site (nothing outside one)."""
  if _active:
    point(_active[-1], "during")

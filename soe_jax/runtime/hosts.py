"""Several hosts, one set of files: in a multi-host run (`jax.distributed`, `sharding`) every process
computes the same run in step, and only process 0 writes. The others' writes go to their temporary
names and are dropped there (`atomic.replacing`), so they run every line of the same code, orbax's
collective saves included, and never touch a file. The processes meet before and after each write site
(`faults.site`): before, so that no process reads a file process 0 has just written while deciding
what the others decided without it (a phase done, a config saved); after, so that what process 0 wrote
is there for every process's next read. The run directory must be on a file system all hosts see.

Without jax imported, or with one process, this process is the writer and a barrier is nothing.
"""

from __future__ import annotations

import itertools
import sys

_barriers = itertools.count()
# The jax minor version whose private coordination-service client (`_wait_at_barrier`) was checked;
# pyproject.toml pins jax to it. Another version: check that the call still exists, then change this.
JAX_CHECKED = (0, 10)


def _jax():
  return sys.modules.get("jax")


def count() -> int:
  """The number of processes in the run (1 without jax)."""
  jax = _jax()
  return 1 if jax is None else jax.process_count()


def writer() -> bool:
  """Whether this process writes the run's files (process 0)."""
  jax = _jax()
  return jax is None or jax.process_index() == 0


def barrier(name: str, timeout_s: float = 24 * 3600) -> None:
  """Wait until every process has reached the barrier `name` (nothing with one process). Every process
  passes the same barriers in the same order; `timeout_s` long, for a wait on another run's lock."""
  if count() == 1:
    return
  _wait_at_barrier(f"soe_jax {next(_barriers)} {name}", int(timeout_s * 1000))


def _wait_at_barrier(name: str, timeout_ms: int) -> None:
  """The coordination service's barrier (no collective, no 30 s timeout), which jax reaches only
  through its private modules: refused, naming the version, under a jax other than `JAX_CHECKED`."""
  jax = _jax()
  version = tuple(int(part) for part in jax.__version__.split(".")[:2])
  if version != JAX_CHECKED:
    raise RuntimeError(
      f"runtime/hosts.py waits at barriers through jax's private jax._src.distributed, checked with jax "
      f"{'.'.join(map(str, JAX_CHECKED))}; this is jax {jax.__version__}: check that "
      "global_state.client.wait_at_barrier is still there, then update hosts.JAX_CHECKED"
    )
  from jax._src import distributed  # (private: imported only here, after the check)

  distributed.global_state.client.wait_at_barrier(name, timeout_ms)

"""One process at a time in a shared directory: an exclusive `fcntl.flock` on a file there, held while the
work is done. The kernel releases it when its holder ends in any way (a kill included), so no lock
outlives its process; the file itself means nothing and stays. In a multi-host run process 0 holds it
for all (`hosts`): the others wait for it to have it, then work beside it."""

from __future__ import annotations

import contextlib
import fcntl
import os
from collections.abc import Iterator

from soe_jax.runtime import hosts


@contextlib.contextmanager
def held(path: str, waiting: str = "") -> Iterator[None]:
  """Hold the lock on `path` (made if missing) for the block; if another process holds it, print
  `waiting` once and wait for it."""
  if not hosts.writer():
    hosts.barrier(f"lock {path}")
    yield
    return
  os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
  with open(path, "a+") as f:
    try:
      fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
      if waiting:
        print(waiting, flush=True)
      fcntl.flock(f, fcntl.LOCK_EX)
    hosts.barrier(f"lock {path}")
    try:
      yield
    finally:
      fcntl.flock(f, fcntl.LOCK_UN)

"""Files written atomically: into a temporary name beside the target, then renamed over it, so that a
reader (or a resumed run) sees the old file or the new one, never half of one."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import sys
from collections.abc import Iterator


@contextlib.contextmanager
def replacing(path: str, suffix: str = "") -> Iterator[str]:
  """Yield a temporary path to write to; on success it replaces `path` (a file or a directory), on an
  error it is removed. `suffix`: the temporary name's ending, for writers that go by it (".mp4")."""
  tmp = f"{path}.tmp-{os.getpid()}{suffix}"
  try:
    yield tmp
  except BaseException:
    _remove(tmp)
    raise
  if os.path.isdir(path) and not os.path.islink(path):
    shutil.rmtree(path)
  os.replace(tmp, path)


def _remove(path: str) -> None:
  if os.path.isdir(path) and not os.path.islink(path):
    shutil.rmtree(path, ignore_errors=True)
  elif os.path.exists(path):
    os.remove(path)


def write_json(path: str, obj, indent: int | None = 2) -> None:
  """Write `obj` to `path` as JSON, atomically and durably (on disk before it is renamed into place)."""
  with replacing(path) as tmp, open(tmp, "w") as f:
    json.dump(obj, f, indent=indent)
    f.flush()
    os.fsync(f.fileno())


def read_json(path: str):
  with open(path) as f:
    return json.load(f)


def read_record(path: str):
  """A record that marks something done -> its content, or None when it is missing, empty or not
  JSON (a write cut short on a file system that does not order them): "not done"."""
  try:
    with open(path) as f:
      return json.load(f)
  except FileNotFoundError:
    return None
  except ValueError:
    print(f"warning: {path} is empty or not JSON: taken as not done", file=sys.stderr, flush=True)
    return None

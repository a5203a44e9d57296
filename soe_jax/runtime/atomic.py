"""Files written atomically: into a temporary name beside the target, then renamed over it, so that a
reader (or a resumed run) sees the old file or the new one, never half of one."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
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
  """Write `obj` to `path` as JSON, atomically."""
  with replacing(path) as tmp, open(tmp, "w") as f:
    json.dump(obj, f, indent=indent)


def read_json(path: str):
  with open(path) as f:
    return json.load(f)

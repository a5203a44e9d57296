"""Config files outside flag parsing: `configs/<task>.py[:PRESETS]` loaded as `--config=` would load
it, and the keys a config has (for "did you mean" on a misspelled override). A relative path that the
current directory lacks is looked up in the repository the package runs from (`resolve`), so the
repository's configs work from any directory."""

from __future__ import annotations

import ast
import difflib
import importlib.util
import os

import ml_collections

from soe_jax.runtime.errors import UserError

# The repository the package runs from (installed editable, `pip install -e .`), which holds `configs/`.
REPO_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def load(spec: str, presets: str = "", overrides: dict | None = None) -> ml_collections.ConfigDict:
  """The config `configs/<task>.py[:PRESETS]` gives with `presets` appended, then `overrides`
  ({"a.b": value})."""
  path, _, own = spec.partition(":")
  path = resolve(path)
  check(path)
  module_spec = importlib.util.spec_from_file_location("soe_config", path)
  module = importlib.util.module_from_spec(module_spec)
  module_spec.loader.exec_module(module)
  config = module.get_config(",".join(p for p in (own, presets) if p))
  config.update_from_flattened_dict(dict(overrides or {}))
  return config


def resolve(path: str) -> str:
  """The config file `path` names: as given where it exists or is absolute; else, relative to the
  repository's root (`REPO_ROOT`: `configs/lift.py` from any directory) where it is there; else as given."""
  if os.path.exists(path) or os.path.isabs(path):
    return path
  in_repo = os.path.join(REPO_ROOT, path)
  return in_repo if os.path.exists(in_repo) else path


def check(path: str) -> None:
  """Refuse a config file that cannot be one, without running it: missing, a directory, not text, not
  Python, or without a top-level `get_config` (`UserError` naming the file and what is wrong)."""
  if not os.path.exists(path):
    where = f"the current directory, {os.getcwd()}"
    if os.path.isdir(os.path.join(REPO_ROOT, "configs")):
      where += f", or the repository's root, {REPO_ROOT}"
    where = "" if os.path.isabs(path) else f" (a relative path is from {where})"
    raise UserError(f"no config file at {path!r}{where}")
  if not os.path.isfile(path):
    raise UserError(f"config file {path!r} is a directory, not a Python file")
  try:
    with open(path, "rb") as f:
      tree = ast.parse(f.read(), path)
  except SyntaxError as e:
    raise UserError(f"config file {path!r}: line {e.lineno}: {e.msg}") from None
  except (UnicodeDecodeError, ValueError) as e:
    raise UserError(f"config file {path!r} is not a Python file: {e}") from None
  names = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
  names |= {t.id for n in tree.body if isinstance(n, ast.Assign) for t in n.targets if isinstance(t, ast.Name)}
  names |= {a.asname or a.name for n in tree.body if isinstance(n, ast.ImportFrom) for a in n.names}
  if "get_config" not in names:
    raise UserError(f"config file {path!r} defines no get_config(arg) (an empty or foreign file?)")


def keys(config: ml_collections.ConfigDict, prefix: str = "") -> list[str]:
  """Every field of `config` as 'a.b.c'."""
  out = []
  for k, v in config.items():
    out += keys(v, f"{prefix}{k}.") if isinstance(v, ml_collections.ConfigDict) else [f"{prefix}{k}"]
  return out


def unknown_overrides(spec: str, argv: list[str]) -> list[str]:
  """For each `--config.a.b=v` in `argv` naming no field of the config file: 'a.b (did you mean a.c?)'."""
  known = keys(load(spec))
  out = []
  for arg in argv:
    if arg.startswith("--config."):
      key = arg[len("--config.") :].split("=", 1)[0]
      if key not in known and not any(k.startswith(key + ".") for k in known):
        close = _closest(key, known)
        out.append(key + (f" (did you mean {close}?)" if close else ""))
  return out


def _closest(key: str, known: list[str]) -> str | None:
  """The known field most like `key`: among its siblings if its section exists (by the last name),
  else among all; by the longest run of characters they share, then similarity."""
  section, _, last = key.rpartition(".")
  siblings = [k for k in known if k.rpartition(".")[0] == section]
  word, candidates = (last, siblings) if siblings else (key, known)

  def score(k: str) -> tuple[float, float]:
    other = k.rpartition(".")[2] if siblings else k
    m = difflib.SequenceMatcher(None, word, other)
    return m.find_longest_match(0, len(word), 0, len(other)).size / len(word), m.ratio()

  best = max(candidates, key=score)
  return best if score(best)[0] >= 0.6 else None

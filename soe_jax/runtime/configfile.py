"""Config files outside flag parsing: `configs/<task>.py[:PRESETS]` loaded as `--config=` would load
it, and the keys a config has (for "did you mean" on a misspelled override)."""

from __future__ import annotations

import difflib
import importlib.util
import os

import ml_collections

from soe_jax.runtime.errors import UserError


def load(spec: str, presets: str = "", overrides: dict | None = None) -> ml_collections.ConfigDict:
  """The config `configs/<task>.py[:PRESETS]` gives with `presets` appended, then `overrides`
  ({"a.b": value})."""
  path, _, own = spec.partition(":")
  if not os.path.exists(path):
    raise UserError(f"no config file at {path!r}")
  module_spec = importlib.util.spec_from_file_location("soe_config", path)
  module = importlib.util.module_from_spec(module_spec)
  module_spec.loader.exec_module(module)
  config = module.get_config(",".join(p for p in (own, presets) if p))
  config.update_from_flattened_dict(dict(overrides or {}))
  return config


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

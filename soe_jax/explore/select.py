"""Which exploration episodes a round keeps (DESIGN.md data flow: "select successes"), by name
(`rounds.select`).

Each takes `success` (S, k): k tries from each of S start states, and returns a (S, k) bool mask.
- `first_success` (default): each start state's first successful try.
- `all_successes`: every successful try.
- `sime`: SIME's `train_0.5` selection (specs/sime_baseline.md): the successes of start states whose
  success rate over their tries is below 0.5; easier states are dropped whole.
"""

from __future__ import annotations

import numpy as np

from soe_jax.registry import Registry

SELECTIONS: Registry[np.ndarray] = Registry("selection")


def first_success(s: np.ndarray) -> np.ndarray:
  first = np.zeros_like(s)
  rows = np.flatnonzero(s.any(axis=1))
  first[rows, s[rows].argmax(axis=1)] = True
  return first


def all_successes(s: np.ndarray) -> np.ndarray:
  return s.copy()


def sime(s: np.ndarray, threshold: float = 0.5) -> np.ndarray:
  return s & (s.mean(axis=1, keepdims=True) < threshold)


SELECTIONS.register("first_success", first_success)
SELECTIONS.register("all_successes", all_successes)
SELECTIONS.register("sime", sime)


def select(success, how: str = "first_success") -> np.ndarray:
  """The (S, k) mask of the tries selection `how` keeps."""
  return SELECTIONS.make(how, np.asarray(success, bool))

"""Which exploration episodes a round keeps (DESIGN.md data flow: "select successes"), by name
(`rounds.select`), optionally only those no longer than a cap (`rounds.length_cap`).

Each rule takes `success` and `length` (S, k): k tries from each of S start states, and the actions
each took; it returns a (S, k) bool mask.
- `first_success` (default): each start state's first successful try.
- `shortest_success`: each start state's shortest successful try (the first of equal ones).
- `all_successes`: every successful try.
- `sime`: SIME's `train_0.5` selection (specs/sime_baseline.md): the successes of start states whose
  success rate over their tries is below 0.5; easier states are dropped whole.
"""

from __future__ import annotations

import numpy as np

from soe_jax.registry import Registry

SELECTIONS: Registry[np.ndarray] = Registry("selection")


def first_success(s: np.ndarray, length: np.ndarray) -> np.ndarray:
  first = np.zeros_like(s)
  rows = np.flatnonzero(s.any(axis=1))
  first[rows, s[rows].argmax(axis=1)] = True
  return first


def shortest_success(s: np.ndarray, length: np.ndarray) -> np.ndarray:
  shortest = np.zeros_like(s)
  rows = np.flatnonzero(s.any(axis=1))
  shortest[rows, np.where(s, length, np.iinfo(np.int64).max)[rows].argmin(axis=1)] = True
  return shortest


def all_successes(s: np.ndarray, length: np.ndarray) -> np.ndarray:
  return s.copy()


def sime(s: np.ndarray, length: np.ndarray, threshold: float = 0.5) -> np.ndarray:
  return s & (s.mean(axis=1, keepdims=True) < threshold)


SELECTIONS.register("first_success", first_success)
SELECTIONS.register("shortest_success", shortest_success)
SELECTIONS.register("all_successes", all_successes)
SELECTIONS.register("sime", sime)


def select(success, length, how: str = "first_success", max_length: float | None = None) -> np.ndarray:
  """The (S, k) mask of the tries selection `how` keeps; with `max_length`, a success that took more
  actions counts as a failure (for every rule, SIME's success rate included)."""
  success, length = np.asarray(success, bool), np.asarray(length, np.int64)
  if max_length:
    success = success & (length <= max_length)
  return SELECTIONS.make(how, success, length)

"""Which exploration episodes a round keeps (DESIGN.md data flow: "select successes").

All take `success` (S, k): k tries from each of S start states, and return a (S, k) bool mask.
- `first_success` (default): each start state's first successful try.
- `all_successes`: every successful try.
- `sime`: SIME's `train_0.5` selection (specs/sime_baseline.md): the successes of start states whose
  success rate over their tries is below 0.5; easier states are dropped whole.
"""

from __future__ import annotations

import numpy as np

SELECTIONS = ("first_success", "all_successes", "sime")


def check_name(how: str) -> None:
  if how not in SELECTIONS:
    raise ValueError(f"unknown selection {how!r}; known selections: {', '.join(SELECTIONS)}")


def select(success, how: str = "first_success", sime_threshold: float = 0.5) -> np.ndarray:
  check_name(how)
  s = np.asarray(success, bool)
  if how == "first_success":
    first = np.zeros_like(s)
    rows = np.flatnonzero(s.any(axis=1))
    first[rows, s[rows].argmax(axis=1)] = True
    return first
  if how == "all_successes":
    return s.copy()
  return s & (s.mean(axis=1, keepdims=True) < sime_threshold)  # sime

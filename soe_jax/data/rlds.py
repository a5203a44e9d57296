"""Episodes as an RLDS dataset through tensorflow-datasets (the Open-X line of models reads these), and
read back exactly. Needs the `rlds` extra (`pip install -e ".[rlds]"`); TensorFlow is not needed:
the dataset is written and read in TFDS's `array_record` file format.

Layout (RLDS: github.com/google-research/rlds): one TFDS dataset `soe_jax_episodes` (version 1.0.0)
under the given directory, split `train`, one example per episode:
- `steps`: T + 1 steps for an episode of T actions. Step t < T holds `observation` {key: (d,)} (the
  observation before action t), `action` (A,), `reward` (1 at the last action of a successful
  episode, else 0), `discount` 1, `state` (1 + nq + nv,) float64 (kept as its bytes: TFDS stores
  floats as float32), `is_first` (t = 0), and `is_last` and `is_terminal` false; step T holds the observation after the last action, with `is_last` true,
  `is_terminal` the episode's success, and zeros for action, reward, discount and state (RLDS's
  convention: a last step's action is not taken).
- `episode_metadata`: `task`, `source` (0 for demonstrations, r for round r's exploration),
  `steered`, `success`, `length` (T), and `soe_jax`: the writer's metadata as JSON.
"""

from __future__ import annotations

import json
import os

import numpy as np

from soe_jax.data.episodes import EpisodeSet
from soe_jax.runtime import atomic
from soe_jax.runtime.errors import UserError

NAME, VERSION = "soe_jax_episodes", "1.0.0"


def _tfds():
  try:
    import tensorflow_datasets as tfds
  except ImportError:
    raise UserError('the RLDS format needs the rlds extra: pip install -e ".[rlds]"') from None
  return tfds


def _builder_class(tfds, features):
  class Builder(tfds.core.GeneratorBasedBuilder, skip_registration=True):
    VERSION = tfds.core.Version(VERSION)

    def __init__(self, examples=(), **kwargs):
      self._examples = examples
      super().__init__(**kwargs)

    def _info(self):
      return tfds.core.DatasetInfo(builder=self, features=features, disable_shuffling=True)  # episodes in order

    def _split_generators(self, dl_manager):
      return {"train": self._generate_examples()}

    def _generate_examples(self):
      yield from enumerate(self._examples)

  Builder.name = NAME
  return Builder


def _features(tfds, ep: dict):
  tensor = lambda x, dtype, **kw: tfds.features.Tensor(shape=np.shape(x)[1:], dtype=dtype, **kw)
  step = dict(
    observation={k: tensor(v, np.float32) for k, v in ep["obs"].items()},
    action=tensor(ep["actions"], np.float32),
    reward=tfds.features.Scalar(dtype=np.float32),
    discount=tfds.features.Scalar(dtype=np.float32),
    state=tensor(ep["states"], np.float64, encoding=tfds.features.Encoding.BYTES),  # (its float lists are float32)
    is_first=np.bool_,
    is_last=np.bool_,
    is_terminal=np.bool_,
  )
  meta = dict(
    task=tfds.features.Text(), source=np.int64, steered=np.bool_, success=np.bool_, length=np.int64,
    soe_jax=tfds.features.Text(),
  )  # fmt: skip
  return tfds.features.FeaturesDict(dict(steps=tfds.features.Dataset(step), episode_metadata=meta))


def _example(ep: dict, s: EpisodeSet, meta: dict) -> dict:
  t, success = len(ep["actions"]), bool(ep.get("success", True))
  states = np.asarray(ep["states"], np.float64)
  steps = []
  for i in range(t + 1):
    last = i == t
    obs = {k: (ep["next_obs"][k][t - 1] if last else v[i]) for k, v in ep["obs"].items()}
    steps.append(
      dict(
        observation={k: np.asarray(v, np.float32) for k, v in obs.items()},
        action=np.zeros_like(ep["actions"][0]) if last else np.asarray(ep["actions"][i], np.float32),
        reward=np.float32(success and i == t - 1),
        discount=np.float32(not last),
        state=np.zeros_like(states[0]) if last else states[i],
        is_first=i == 0,
        is_last=last,
        is_terminal=last and success,
      )
    )
  episode_meta = dict(
    task=str(meta.get("env_name", "")), source=s.source, steered=s.steered, success=success, length=t,
    soe_jax=json.dumps(meta, sort_keys=True),
  )  # fmt: skip
  return dict(steps=steps, episode_metadata=episode_meta)


def write(path: str, sets: list[EpisodeSet], meta: dict) -> None:
  """Write the episodes of `sets` (each with `states` and `next_obs`), in order, as the dataset under
  the directory `path` (replacing it)."""
  tfds = _tfds()
  episodes = [(ep, s) for s in sets for ep in s.episodes]
  if not episodes:
    raise ValueError("no episodes to write")
  missing = [i for i, (ep, _) in enumerate(episodes) if "states" not in ep or "next_obs" not in ep]
  if missing:
    raise ValueError(f"episodes {missing[:5]} lack states or next_obs, which RLDS's steps need")
  examples = [_example(ep, s, meta) for ep, s in episodes]
  with atomic.replacing(path) as tmp:
    builder = _builder_class(tfds, _features(tfds, episodes[0][0]))(examples, data_dir=tmp, file_format="array_record")
    builder.download_and_prepare()


def read(path: str) -> tuple[list[EpisodeSet], dict]:
  """A dataset written by `write` (the directory given to it) -> (its groups in order of first
  appearance, the writer's metadata). One that cannot be read (missing, damaged or truncated files, a
  different schema) is a `ValueError` naming it."""
  tfds = _tfds()
  version_dir = os.path.join(path, NAME, VERSION)
  if not os.path.isdir(version_dir):
    raise ValueError(f"{path!r} holds no RLDS dataset {NAME}/{VERSION} (not written by this exporter)")
  try:
    return _read(tfds, version_dir)
  except Exception as e:  # tfds', array_record's, protobuf's or JSON's errors
    raise ValueError(f"RLDS dataset {path!r} cannot be read: {type(e).__name__}: {str(e)[:300]}") from e


def _read(tfds, version_dir: str) -> tuple[list[EpisodeSet], dict]:
  source = tfds.builder_from_directory(version_dir).as_data_source()["train"]
  groups: dict[tuple, list] = {}
  meta = {}
  for i in range(len(source)):
    example = source[i]
    m = example["episode_metadata"]
    steps = [example["steps"][j] for j in range(len(example["steps"]))]
    t = int(m["length"])
    obs = {k: np.stack([s["observation"][k] for s in steps]) for k in steps[0]["observation"]}
    ep = dict(
      obs={k: v[:t] for k, v in obs.items()},
      next_obs={k: v[1:] for k, v in obs.items()},
      actions=np.stack([s["action"] for s in steps[:t]]),
      states=np.stack([s["state"] for s in steps[:t]]),
      success=bool(m["success"]),
    )
    text = m["soe_jax"]
    meta = json.loads(text.decode() if isinstance(text, bytes) else text)
    groups.setdefault((int(m["source"]), bool(m["steered"])), []).append(ep)
  return [EpisodeSet(eps, src, st) for (src, st), eps in groups.items()], meta

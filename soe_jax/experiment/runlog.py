"""A run's log: `metrics.jsonl` (one JSON line per round and phase), TensorBoard event files under
`tb/`, a one-line summary per phase on the console, and the time spent compiling (from JAX's
compilation events), so that phase wall times can be split into compile and work."""

from __future__ import annotations

import json
import os
import sys
import threading
import time
import uuid

import jax
import numpy as np
from tensorboardX import SummaryWriter

from soe_jax.runtime import faults, hosts, provenance
from soe_jax.runtime.console import duration
from soe_jax.runtime.errors import UserError

_COMPILE_EVENTS = (
  "/jax/core/compile/jaxpr_trace_duration",
  "/jax/core/compile/jaxpr_to_mlir_module_duration",
  "/jax/core/compile/backend_compile_duration",
)


class CompileTimer:
  """Seconds JAX spent tracing, lowering and compiling since the last `take()`."""

  def __init__(self):
    self._lock = threading.Lock()
    self._seconds = 0.0
    jax.monitoring.register_event_duration_secs_listener(self._listen)

  def _listen(self, event: str, duration: float, **kwargs) -> None:
    if event in _COMPILE_EVENTS:
      with self._lock:
        self._seconds += duration

  def take(self) -> float:
    with self._lock:
      seconds, self._seconds = self._seconds, 0.0
    return seconds

  def close(self) -> None:
    jax.monitoring.unregister_event_duration_listener(self._listen)


def flatten(d: dict, prefix: str = "") -> dict:
  """A saved config as {'a.b': value}."""
  out = {}
  for k, v in d.items():
    key = f"{prefix}{k}"
    if isinstance(v, dict):
      out.update(flatten(v, key + "."))
    else:
      out[key] = list(v) if isinstance(v, tuple) else v
  return out


def read_metrics(workdir: str, repair: bool = False) -> list[dict]:
  """The lines of `metrics.jsonl`. A torn last line (a write cut by a kill: no newline at its end) is left
  out, and with `repair` cut from the file with a one-line warning; its phase's record was written before
  it, so the phase is finished and the resumed run writes its line again. A bad line elsewhere is an
  error naming the file and the line."""
  path = os.path.join(workdir, "metrics.jsonl")
  if not os.path.exists(path):
    return []
  with open(path, "rb") as f:
    data = f.read()
  body, newline, torn = data.rpartition(b"\n")
  out = []
  for i, raw in enumerate(body.split(b"\n") if newline else []):
    if raw.strip():
      try:
        out.append(json.loads(raw))
      except ValueError:
        raise UserError(f"{path}: line {i + 1} is not JSON ({raw[:60]!r}); the log is damaged") from None
  if torn.strip() and repair:
    with open(path, "r+b") as f:
      f.truncate(len(body) + len(newline))
      f.flush()
      os.fsync(f.fileno())
    print(f"warning: {path}: cut a torn last line ({len(torn)} bytes of a write cut short); its phase's line is "
          "written again", file=sys.stderr, flush=True)  # fmt: skip
  return out


LINE_KEYS = (
  "round",
  "phase",
  "method",
  "success_rate",
  "num_rollouts",
  "wilson_low",
  "wilson_high",
  "pass_at_k",
  "k",
  "rollouts",
  "rollouts_mean",
  "jerk",
  "num_episodes",
  "time_compile_s",
  "time_fit_s",
  "time_explore_s",
  "time_evaluate_s",
  "time_total_s",
)
PHASE_TIMES = ("time_fit_s", "time_explore_s", "time_evaluate_s")


def line(record: dict, method: str) -> dict:
  """The metrics.jsonl line of a phase record: the common keys first (None where a phase has no such
  number), then the phase's own; per-episode lists stay in the phase's JSON file."""
  out = {k: record.get(k) for k in LINE_KEYS}
  out.update(method=method, **dict.fromkeys(PHASE_TIMES, 0.0))
  out[f"time_{record['phase']}_s"] = round(record["time_total_s"] - record["time_compile_s"], 2)
  out.update({k: v for k, v in record.items() if k not in out and k not in ("success", "loss_curve", "eval_curve")})
  return out


class RunLog:
  """The log of the run in `workdir`, as a context manager; `once` writes a phase's line unless an
  earlier (interrupted) run of the same workdir already did. With `wandb` (`config.log.wandb`), each
  line also goes to a wandb run (`WandbLog`)."""

  def __init__(self, workdir: str, wandb: WandbLog | None = None):
    self.path = os.path.join(workdir, "metrics.jsonl")
    self.logged = {(m["round"], m["phase"]) for m in read_metrics(workdir, repair=hosts.writer())}
    self.writer = SummaryWriter(os.path.join(workdir, "tb")) if hosts.writer() else None
    self.wandb = wandb

  def __enter__(self) -> RunLog:
    return self

  def __exit__(self, *exc) -> None:
    self.close()

  def once(self, record: dict, method: str) -> None:
    if (record["round"], record["phase"]) not in self.logged:
      self.write(line(record, method))
      self.logged.add((record["round"], record["phase"]))

  def write(self, record: dict) -> None:
    """Append one phase's record (and its numbers to TensorBoard, stepped by round): the write site
    "metrics_line", whose `during` point has half the line on disk (a torn line, `read_metrics`). A
    host other than the writer (`hosts`) only prints it."""
    with faults.site("metrics_line"):
      if self.writer is not None:
        self._append(json.dumps(record) + "\n")
        for k, v in record.items():
          if isinstance(v, (int, float)) and not isinstance(v, bool) and k != "round":
            self.writer.add_scalar(f"{record['phase']}/{k}", v, record["round"])
        self.writer.flush()
    if self.wandb is not None:
      self.wandb.log(record)
    print(summary_line(record), flush=True)

  def _append(self, text: str) -> None:
    with open(self.path, "a") as f:
      size = f.tell()
      try:
        half = len(text) // 2
        for i, part in enumerate((text[:half], text[half:])):
          f.write(part)
          f.flush()
          os.fsync(f.fileno())
          if i == 0:
            faults.during()
      except OSError:  # a full disk: no half line left behind
        f.truncate(size)
        raise

  def close(self) -> None:
    if self.writer is not None:
      self.writer.close()
    if self.wandb is not None:
      self.wandb.close()


class WandbLog:
  """A wandb run for the run in `workdir`: named after the workdir, with the config and the commit
  as its config, resumed by the id it saved there (so an interrupted run continues the same wandb
  run); each phase's numbers logged at step = its round. wandb's own settings hold (WANDB_MODE=offline:
  on disk only, under <workdir>/wandb; WANDB_DIR, WANDB_ENTITY, ...)."""

  ID_FILE = "wandb_id.txt"

  def __init__(self, workdir: str, config: dict, project: str):
    import wandb  # here, not at the top: an optional extra (`pip install -e ".[wandb]"`)

    id_path = os.path.join(workdir, self.ID_FILE)
    if not os.path.exists(id_path):
      with open(id_path, "w") as f:
        f.write(uuid.uuid4().hex[:12])
    with open(id_path) as f:
      run_id = f.read().strip()
    self.run = wandb.init(
      project=project,
      dir=os.environ.get("WANDB_DIR", workdir),
      name=os.path.basename(os.path.abspath(workdir)),
      id=run_id,
      resume="allow",
      config=dict(config, commit=provenance.commit()),
    )

  def log(self, record: dict) -> None:
    numbers = {
      f"{record['phase']}/{k}": v
      for k, v in record.items()
      if isinstance(v, (int, float)) and not isinstance(v, bool) and k != "round"
    }
    self.run.log(numbers, step=int(record["round"]))

  def close(self) -> None:
    self.run.finish()


class RoundClock:
  """The whole run's progress on the console: round r of R, the time since the start, and how long the
  remaining rounds take: at the pace of the rounds after round 0 run in this process, or before any
  has run, as `expected` says (round 0's pace, `round_estimate`)."""

  def __init__(self, num_rounds: int):
    self.num_rounds, self.start, self.took = num_rounds, time.perf_counter(), []

  def begin(self, r: int, expected: float | None = None) -> None:
    now = time.perf_counter()
    if r > 1:
      self.took.append(now - self.round_start)
    self.round_start = now
    per_round, pace = (np.mean(self.took), "") if self.took else (expected, " at round 0's pace")
    left = f", about {duration(per_round * (self.num_rounds - r + 1))} left{pace}" if per_round else ""
    print(f"== round {r} of {self.num_rounds} (elapsed {duration(now - self.start)}{left})", flush=True)


def round_estimate(config, fit0: dict, evaluate0: dict) -> float:
  """Seconds a round after round 0 should take at round 0's pace: its re-fit at round 0's time per step,
  its exploration and evaluation at round 0's time per evaluation episode (compiling not counted)."""
  per_step = fit0["time_steps_s"] / max(fit0["steps"], 1)
  per_episode = max(evaluate0["time_total_s"] - evaluate0["time_compile_s"], 0.0) / max(evaluate0["num_rollouts"], 1)
  steps = config.rounds.refit_steps if config.rounds.refit == "continue" else config.fit.num_steps
  explored = 0 if config.rounds.new_data == "none" else config.explore.num_start_states * config.explore.tries
  return per_step * steps + per_episode * (explored + config.eval.num_start_states)


def summary_line(r: dict) -> str:
  """A phase's line on the console: its numbers in groups separated by "; ", then its time."""
  parts = []
  if r.get("success_rate") is not None:
    parts.append(
      f"success {r['success_rate']:.1%} of {r['num_rollouts']} [{r['wilson_low']:.1%}, {r['wilson_high']:.1%}]"
    )
  if r.get("pass_at_k") is not None:
    parts.append(
      f"Pass@{r['k']} {r['pass_at_k']:.1%}, rollouts {r['rollouts']} ({r['rollouts_mean']:.2f}/state), "
      f"jerk {r['jerk']:.1f} m/s^3, kept {r['num_episodes']}"
    )
  if r.get("obs_out_of_range") is not None:
    parts.append(f"observation features out of range (beyond the demonstrations' span) {r['obs_out_of_range']:.1%}")
  if r.get("final_loss") is not None:
    parts.append(f"loss {r['final_loss']:.4f} after {r['steps']} steps on {r['num_episodes']} episodes")
  timing = f"({r['time_total_s']:.0f} s, compile {r['time_compile_s']:.0f} s)"
  return " ".join(x for x in (f"round {r['round']} {r['phase']}:", "; ".join(parts), timing) if x)

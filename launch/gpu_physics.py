"""Physics throughput on a GPU host: MJX with MuJoCo Warp and with MJX-JAX, and the C engine on the
host's CPUs, every task at 256 / 2,048 / 4,096 / 8,192 environments, with compile times; then the MJX
scene's acceptance checks (`python -m soe_jax bench mjx`: the demonstrator on 200 start states, the
end-effector paths against the C engine) and one policy rollout at 2,048 environments on the GPU.

  python launch/gpu_physics.py [--budget=290] [--cap=75] [--out=DIR]

Each case is one `python -m soe_jax bench ...` process with its own time cap (compile included); the
cases run in priority order until the budget is spent, and the ones left are listed as not run.
After every case, DIR/physics.jsonl (one record per case), DIR/physics.md (the table) and
DIR/physics.png (control steps/s against environments) are rewritten, so a run cut short keeps what
it measured. MJX-JAX is left out for can and square (Can's scene did not compile in 560 s on an H100).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

SIZES = (256, 4096, 8192, 2048)  # the target size (4,096) early


def cases() -> list[tuple[str, list[str]]]:
  """(name, the arguments of `python -m soe_jax`) of every case, in priority order."""
  env = lambda task, backend, n, impl="": (
    f"env {task} {backend}{'-' + impl if impl else ''} {n}",
    ["bench", "env", f"--task={task}", f"--backend={backend}", f"--num_envs={n}", "--steps=10", "--repeats=2"]
    + ([f"--mjx_impl={impl}"] if impl else []),
  )
  out = [env("lift", "mjx", n, "warp") for n in SIZES]
  out += [env(t, "mjx", 4096, "warp") for t in ("square", "can")]
  out += [env(t, "mujoco", 2048) for t in ("lift", "can", "square")]
  out += [(f"mjx {t} warp 200", ["bench", "mjx", f"--task={t}", "--mjx_impl=warp", "--num_envs=200", "--progress=false"])
          for t in ("lift", "can", "square")]  # fmt: skip
  out += [env(t, "mjx", n, "warp") for t in ("square", "can") for n in SIZES if n != 4096]
  out += [env("lift", "mjx", n, "jax") for n in (256, 4096)]
  out += [
    (
      "rollout lift mjx-warp 2048",
      ["bench", "rollout", "--config=configs/lift.py:cpu", "--config.env.backend=mjx", "--config.env.mjx_impl=warp",
       "--strategy=soe", "--num_envs=2048"],
    )
  ]  # fmt: skip
  out += [env(t, "mujoco", 256) for t in ("lift", "can", "square")]
  return out


def command(args: list[str], module: str = "soe_jax") -> list[str]:
  """The command line of a case: `python -m module *args`."""
  return [sys.executable, "-m", module, *args]


def run_case(args: list[str], cap: float, module: str = "soe_jax") -> dict:
  """`python -m module *args`, killed after `cap` seconds; a benchmark's result (`python -m soe_jax
  bench ...`) is its last JSON line (other commands: none)."""
  t = time.perf_counter()
  try:
    p = subprocess.run(command(args, module), capture_output=True, text=True, timeout=cap)
  except subprocess.TimeoutExpired:
    return dict(status=f"timed out after {cap:.0f} s", wall_s=round(time.perf_counter() - t, 1))
  wall = round(time.perf_counter() - t, 1)
  lines = [line for line in p.stdout.splitlines() if line.startswith("{")]
  if p.returncode or (module == "soe_jax" and args[:1] == ["bench"] and not lines):
    return dict(status=f"failed (exit {p.returncode})", wall_s=wall, error=(p.stderr or p.stdout)[-1500:])
  return dict(status="ok", wall_s=wall, **(dict(result=json.loads(lines[-1])) if lines else {}))


def pyplot():
  """matplotlib's pyplot drawing to files, or None where the host lacks matplotlib (the tables still
  get written)."""
  try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
  except ImportError:
    return None
  return plt


def write(out: str, records: list[dict], left: list[str]) -> None:
  with open(os.path.join(out, "physics.jsonl"), "w") as f:
    f.writelines(json.dumps(r) + "\n" for r in records)
  md = ["| case | status | control steps/s | compile s | wall s | other |", "|---|---|---|---|---|---|"]
  for r in records:
    res = r.get("result", {})
    other = {k: res[k] for k in ("success_rate", "path_gap_max_m", "peak", "mjx_settings") if k in res}
    md.append(
      f"| {r['case']} | {r['status']} | {res.get('control_steps_per_s', '-')} | {res.get('compile_s', '-')} "
      f"| {r['wall_s']} | {json.dumps(other) if other else ''} |"
    )
  md += [f"| {c} | not run (budget) | | | | |" for c in left]
  with open(os.path.join(out, "physics.md"), "w") as f:
    f.write("\n".join(md) + "\n")
  plt = pyplot()
  if plt is None:
    return
  series: dict[str, list[tuple[int, float]]] = {}
  for r in records:
    res = r.get("result", {})
    if r["case"].startswith("env ") and "control_steps_per_s" in res:
      _, task, backend, n = r["case"].split()
      series.setdefault(f"{task} {backend}", []).append((int(n), res["control_steps_per_s"]))
  fig, ax = plt.subplots(figsize=(6, 4))
  for name, pts in sorted(series.items()):
    pts.sort()
    ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label=name)
  ax.set(xscale="log", yscale="log", xlabel="environments", ylabel="control steps / s (all environments)")
  ax.grid(True, which="both", alpha=0.3)
  if series:
    ax.legend(fontsize=7)
  fig.tight_layout()
  fig.savefig(os.path.join(out, "physics.png"), dpi=120)
  plt.close(fig)


def run_all(todo: list[tuple[str, list[str]]], budget: float, cap: float, write, module: str = "soe_jax") -> None:
  """Run the cases (`python -m module ARGS`) in order until `budget` seconds are spent, each capped at
  `cap`; `write(records, names left)` after every case, so a run cut short keeps what it measured."""
  start = time.perf_counter()
  records = []
  while todo and (left := budget - (time.perf_counter() - start)) >= 15:
    name, args = todo.pop(0)
    print(f"[{time.perf_counter() - start:5.0f} s] {name}", flush=True)
    record = dict(case=name, **run_case(args, min(cap, left), module))
    print(f"        {record['status']}: {json.dumps(record.get('result', {}))[:300]}", flush=True)
    records.append(record)
    write(records, [c for c, _ in todo])
  write(records, [c for c, _ in todo])
  print(f"done in {time.perf_counter() - start:.0f} s; {len(todo)} cases not run", flush=True)


def main() -> None:
  parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
  parser.add_argument("--budget", type=float, default=290, help="seconds for all cases together")
  parser.add_argument("--cap", type=float, default=75, help="seconds for one case, compile included")
  parser.add_argument("--out", default="gpu-physics")
  a = parser.parse_args()
  os.makedirs(a.out, exist_ok=True)
  run_all(cases(), a.budget, a.cap, lambda records, left: write(a.out, records, left))


if __name__ == "__main__":
  main()

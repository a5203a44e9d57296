"""The paper-scale image policy on a GPU host: the ResNet-18 encoder's fit step, the whole image
policy's fit step (two cameras' ResNet-18s and Diffusion Policy's UNet, `configs/lift.py:image`) with
and without the VIB bypass, one action chunk's sampling at 1 and 256 observations, and Lift's control
steps with both cameras drawn by MuJoCo Warp's batch renderer on the GPU at 256 and 1,024 environments.

  python launch/gpu_image.py [--budget=280] [--cap=90] [--presets=image] [--out=DIR]

Each case is one `python -m soe_jax bench ...` process with its own time cap (compile included), run
in order until the budget is spent; after each, DIR/image.jsonl and DIR/image.md are rewritten, so a
run cut short keeps what it measured. `--presets=smoke,image` checks the script on a CPU in minutes.
"""

from __future__ import annotations

import argparse
import json
import os

from gpu_physics import run_all  # (launch/ is the script's directory)


def cases(presets: str) -> list[tuple[str, list[str]]]:
  """(name, the arguments of `python -m soe_jax`) of every case, in order."""
  config = f"--config=configs/lift.py:{presets}"
  return [
    ("encoder resnet18 batch 64", ["bench", "encoder", "--batch=64", "--steps=3", "--repeats=2"]),
    ("fit lift image", ["bench", "fit", config, "--steps=10", "--repeats=2"]),
    (
      "fit lift image, bypass and ema",
      ["bench", "fit", config, "--bypass=on", "--ema=on", "--steps=10", "--repeats=2"],
    ),
    ("sample lift image batch 1", ["bench", "sample", config, "--batch=1"]),
    ("sample lift image batch 256", ["bench", "sample", config, "--batch=256"]),
    *(
      (
        f"render lift warp {n} environments",
        ["bench", "env", "--task=lift", f"--num_envs={n}", "--obs_mode=image"]
        + ["--renderer=warp", "--steps=10", "--repeats=3"],
      )
      for n in (256, 1024)
    ),
  ]


def write(out: str, records: list[dict], left: list[str]) -> None:
  with open(os.path.join(out, "image.jsonl"), "w") as f:
    f.writelines(json.dumps(r) + "\n" for r in records)
  md = ["| case | status | ms per step / chunk (or control steps/s) | first call s | wall s |", "|---|---|---|---|---|"]
  for r in records:
    res = r.get("result", {})
    ms = res.get("ms_per_step", res.get("ms_per_chunk", round(res["step_s"] * 1000, 1) if "step_s" in res else "-"))
    if "control_steps_per_s" in res:
      ms = f"{res['control_steps_per_s']:,.0f} steps/s"
    first = res.get("first_chunk_s", res.get("compile_s", "-"))
    md.append(f"| {r['case']} | {r['status']} | {ms} | {first} | {r['wall_s']} |")
  md += [f"| {c} | not run (budget) | | | |" for c in left]
  with open(os.path.join(out, "image.md"), "w") as f:
    f.write("\n".join(md) + "\n")


def main() -> None:
  parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
  parser.add_argument("--budget", type=float, default=280, help="seconds for all cases together")
  parser.add_argument("--cap", type=float, default=90, help="seconds for one case, compile included")
  parser.add_argument("--presets", default="image", help="the presets of configs/lift.py")
  parser.add_argument("--out", default="gpu-image")
  a = parser.parse_args()
  os.makedirs(a.out, exist_ok=True)
  run_all(cases(a.presets), a.budget, a.cap, lambda records, left: write(a.out, records, left))


if __name__ == "__main__":
  main()

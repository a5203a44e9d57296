#!/usr/bin/env bash
# Run methods x seeds x tasks one after another, then aggregate them into one comparison table.
#   bash launch/compare_methods.sh [PRESET] [SEEDS] [TASKS] [METHODS]
#   bash launch/compare_methods.sh cpu "0 1 2" "lift" "dp sime soe soe_steer"
# Runs land in runs/compare-<PRESET>/<task>/<method>/seed<s>; the methods of one task and seed share
# their round-0 policy in runs/compare-<PRESET>/<task>/round0. Re-running the command resumes
# unfinished runs. On a cluster, run each `python -m soe_jax.main` line as its own job (with a shared
# file system for round0/) and the aggregation at the end.
set -euo pipefail
preset=${1:-cpu}
seeds=${2:-0}
tasks=${3:-lift}
methods=${4:-dp sime soe soe_steer}
root="runs/compare-${preset:-default}"
for task in $tasks; do
  for seed in $seeds; do
    for method in $methods; do
      presets="${preset:+$preset,}$method"
      python -m soe_jax.main --config="configs/$task.py:$presets" --config.seed="$seed" \
        --config.rounds.round0_dir="$root/$task/round0" --workdir="$root/$task/$method/seed$seed" --progress=false \
        | tail -n 1
    done
  done
done
python -m soe_jax.aggregate "$root" --out="$root/comparison"

#!/usr/bin/env bash
# Methods x training seeds x tasks, one `python -m soe_jax campaign` per task and seed (the unit of
# work: it builds that seed's round 0 and runs every method from it, exporting each finished run to
# results/campaign-<PRESET>/<task>/seed<k>/<method>/ and rewriting results/campaign-<PRESET>/comparison.md).
#   bash launch/campaign.sh [TASKS] [SEEDS] [PRESET] [METHODS]
#   bash launch/campaign.sh lift "0 1 2" cpu dp,sime,soe,soe_steer,control,dp+expert_data,soe+expert_data
# Work directories under $RUNS/campaign-<PRESET> (`launch/runs.sh`: RUNS, else the main checkout's runs/).
# Re-running resumes unfinished runs. On a cluster, run each campaign line as its own job.
set -euo pipefail
source "$(dirname "$0")/runs.sh"
tasks=${1:-lift}
seeds=${2:-0 1 2}
preset=${3:-cpu}
methods=${4:-dp,sime,soe,soe_steer,control,dp+expert_data,soe+expert_data}
for task in $tasks; do
  for seed in $seeds; do
    python -m soe_jax campaign --config="configs/$task.py${preset:+:$preset}" --config.seed="$seed" --methods="$methods" \
      --workdir="$(runs_root)/campaign-${preset:-default}" --results="results/campaign-${preset:-default}" --progress=false
  done
done

#!/usr/bin/env bash
# Methods x training seeds x tasks as one `python -m soe_jax campaign` (per task and seed it builds a
# round 0 and runs every method from it, exporting each finished run to
# results/campaign-<PRESET>/<task>/seed<k>/<method>/ and rewriting results/campaign-<PRESET>/comparison.md).
#   bash launch/campaign.sh [TASKS] [SEEDS] [PRESET] [METHODS] [CAMPAIGN FLAGS...]
#   bash launch/campaign.sh lift "0 1 2" cpu dp,sime,soe,soe_steer,control,dp+expert_data,soe+expert_data
#   bash launch/campaign.sh "lift can" "0 1 2" cpu "" --executor=slurm   # on a SLURM cluster, as jobs
# Work directories under $RUNS/campaign-<PRESET> (`launch/runs.sh`: RUNS, else the main checkout's runs/).
# Re-running resumes unfinished runs.
set -euo pipefail
source "$(dirname "$0")/runs.sh"
tasks=${1:-lift}
seeds=${2:-0 1 2}
preset=${3:-cpu}
methods=${4:-dp,sime,soe,soe_steer,control,dp+expert_data,soe+expert_data}
shift $(($# < 4 ? $# : 4))
python -m soe_jax campaign --config="configs/${tasks%% *}.py${preset:+:$preset}" --tasks="${tasks// /,}" \
  --seeds="${seeds// /,}" --methods="$methods" --workdir="$(runs_root)/campaign-${preset:-default}" \
  --results="results/campaign-${preset:-default}" --progress=false "$@"

#!/usr/bin/env bash
# The committed campaign a `configs/lift.py:quick` run's report stands beside (results/quick/): the
# control, dp, sime and soe on Lift under the `quick` preset, one training seed per call (seeds 0, 1 and
# 2 are committed):
#   bash launch/quick.sh SEED [WORKDIR]
# Work directories under WORKDIR, default $RUNS/quick (`launch/runs.sh`: RUNS, else the main checkout's
# runs/, never inside a pinned worktree); re-running resumes. RESULTS (default results) may be set in
# the environment: the seed's runs are copied to $RESULTS/quick/lift/seed<k>/.
set -euo pipefail
source "$(dirname "$0")/runs.sh"
seed=${1:?the training seed}
runs=${2:-$(runs_root)/quick}
python -m soe_jax campaign --config=configs/lift.py:quick --seeds="$seed" --methods=control,dp,sime,soe \
  --workdir="$runs" --results="${RESULTS:-results}/quick" --progress=false

#!/usr/bin/env bash
# Record scripted demonstrations for every task into demos/<task>.hdf5 and print each summary line.
#   bash launch/collect_demos.sh [NUM_EPISODES] [SEED]
set -euo pipefail
n=${1:-200}
seed=${2:-0}
for task in lift can square; do
  python -m soe_jax experts --task="$task" --num_episodes="$n" --seed="$seed" --out="demos/$task.hdf5" | tail -n 1
done

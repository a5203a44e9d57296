#!/usr/bin/env bash
# The experiments that decide each suspect of "why own successes hurt" (README), on Lift with the
# workspace box, one training seed per call so a session can finish it whole:
#   bash launch/why_own_successes.sh SEED [WORKDIR]
# 1. One campaign invocation: the shared control and every arm of suspects 2-5 (alpha 0, the re-fit's
#    demonstration share and aligned windows, the KL weight's dose-response with beta = 0 as the
#    fidelity study's other setting), exported to results/why-own-successes/lift/seed<k>/.
# 2. The relabelled arms (labels against states) from that invocation's dp and soe runs, exported beside.
# 3. The fidelity study on the dp, soe and soe alpha=0 runs (beta 1e-3) and the beta=0 one.
# Work directories outside the work tree (WORKDIR, default /work/runs-why); re-running resumes.
# CONFIG (default configs/lift.py:cpu) and RESULTS (default results) may be set in the environment,
# e.g. CONFIG=configs/lift.py:smoke RESULTS=/tmp/why for a quick check of the whole path.
set -euo pipefail
seed=${1:?the training seed}
runs=${2:-/work/runs-why}
config=${CONFIG:-configs/lift.py:cpu}
out=${RESULTS:-results}
results=$out/why-own-successes
python -m soe_jax campaign --config="$config" --config.seed="$seed" \
  --methods=control,dp,soe,soe+alpha=0,dp+demo_fraction=0.5,soe+demo_fraction=0.5,dp+aligned=true,soe+aligned=true,soe+beta=0.0001,soe+beta=1e-05,soe+beta=0 \
  --workdir="$runs" --results="$results" --progress=false
base="$runs/lift/seed$seed"
for args in "dp --labels=explore --alpha=0" "dp --labels=explore --alpha=2" "soe --labels=base" "dp --labels=base --seed=1"; do
  set -- $args
  python -m soe_jax relabel "$base/$1" "${@:2}" --results="$results" --progress=false
done
python -m soe_jax fidelity "$base/dp" "$base/soe" "$base/soe-alpha0" "$base/soe-beta0" \
  --out="$out/fidelity/lift_seed$seed.json"

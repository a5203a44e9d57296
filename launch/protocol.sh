#!/usr/bin/env bash
# The protocol issue's experiments on Lift, one training seed per call so a session can finish it whole
# (docs/protocol.md is the rule that reads them):
#   bash launch/protocol.sh PART SEED [WORKDIR]
# PART sime-count-N: round 0 and its control (a re-fit from scratch on the same data) under SIME's
#   protocol with N demonstrations, to results/protocol-count/sime-nN/: the demonstration count's
#   calibration and the control's reproducibility check.
# PART varied-count-N: round 0 and its control on N varied demonstrations under the present protocol,
#   to results/protocol-count/varied-nN/: the varied data's count calibration.
# PART sime-N: dp, sime, soe and the control under SIME's protocol with N demonstrations, one
#   invocation, to results/protocol-sime/nN/.
# PART style-N: dp, sime, soe and the control on scripted and on varied demonstrations (N of each,
#   the present protocol), one invocation, to results/demo-style-campaign/nN/; then the latent study
#   (effective dimensions) on each, to results/latent-style/.
# Work directories outside the work tree (WORKDIR, default /work/runs-protocol, one per part);
# re-running resumes. CONFIG (default configs/lift.py:cpu) and RESULTS (default results) may be set in
# the environment, e.g. CONFIG=configs/lift.py:smoke RESULTS=/tmp/protocol for a quick check.
set -euo pipefail
part=${1:?sime-count-N, varied-count-N, sime-N or style-N}
seed=${2:?the training seed}
runs=${3:-/work/runs-protocol}
config=${CONFIG:-configs/lift.py:cpu}
out=${RESULTS:-results}
count=${part##*-}
[[ $count =~ ^[0-9]+$ ]] || { echo "$part: the part ends in its demonstration count, a number" >&2; exit 2; }
campaign() {  # campaign METHODS NAME RESULTS
  python -m soe_jax campaign --config="$config" --config.seed="$seed" --config.data.num_demos="$count" \
    --methods="$1" --workdir="$runs/$2" --results="$out/$3" --progress=false
}
case ${part%-*} in
  sime-count) campaign control+protocol=sime "sime-count-$count" "protocol-count/sime-n$count" ;;
  varied-count) campaign control+style=varied "varied-count-$count" "protocol-count/varied-n$count" ;;
  sime)
    campaign control+protocol=sime,dp+protocol=sime,sime+protocol=sime,soe+protocol=sime "sime-$count" \
      "protocol-sime/n$count"
    ;;
  style)
    campaign control,dp,sime,soe,control+style=varied,dp+style=varied,sime+style=varied,soe+style=varied \
      "style-$count" "demo-style-campaign/n$count"
    for s in scripted varied; do
      python -m soe_jax latent --config="$config,style=$s" --config.seed="$seed" --config.data.num_demos="$count" \
        --workdir="$runs/style-$count-latent/$s/seed$seed" --progress=false \
        --out="$out/latent-style/lift_n${count}_${s}_seed$seed.json"
    done
    ;;
  *)
    echo "$part: unknown part (sime-count-N, varied-count-N, sime-N or style-N)" >&2
    exit 2
    ;;
esac

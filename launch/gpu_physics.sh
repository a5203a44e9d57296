#!/usr/bin/env bash
# On the GPU host (the device tool), after launch/ship_wheels.sh here:
#   bash launch/gpu_physics.sh receive         keep the carried part(s) of .ship/ in /tmp/ship
#   bash launch/gpu_physics.sh run [BUDGET_S]  join the parts, install the wheels under /tmp/site and
#                                              measure (launch/gpu_physics.py; default budget 290 s)
#   SCRIPT=gpu_image bash launch/gpu_physics.sh run [BUDGET_S]   the same, measuring the image policy
#                                              (launch/gpu_image.py) instead
set -uo pipefail
cd "$(dirname "$0")/.."
mkdir -p /tmp/ship
cp .ship/ship.tar.* /tmp/ship/ 2>/dev/null
ls -l /tmp/ship
[ "${1:-}" = run ] || exit 0
if [ ! -d /tmp/site/mujoco ]; then
  n=$(ls /tmp/ship/ship.tar.* | wc -l)
  [ "$n" -eq 4 ] || { echo "have $n of the 4 parts of .ship/ship.tar: carry each part first"; exit 1; }
  cat /tmp/ship/ship.tar.* | tar -xf - -C /tmp/ship || exit 1
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site \
    /tmp/ship/wheels/*.whl || exit 1
fi
export PYTHONPATH=/tmp/site:$PWD PYTHONUNBUFFERED=1
script=${SCRIPT:-gpu_physics}
python3 "launch/$script.py" --budget="${2:-290}" --out="${OUT:-${script//_/-}}"

#!/usr/bin/env bash
# Here, before a GPU session: the wheels the GPU host lacks (MuJoCo, MJX with MuJoCo Warp, brax and
# what they import that the host's image does not have), for its Python 3.12, packed into one tar
# and cut into parts that each fit one device command's 64 MiB with the working tree:
#   bash launch/ship_wheels.sh            -> .ship/ship.tar.00 ... (ignored by git)
# Then, back to back (the host keeps files for ~30 s after a command), one `run` per part with
# carry [".ship/ship.tar.NN"] and the command `bash launch/gpu_physics.sh receive`; the last part's
# command is `bash launch/gpu_physics.sh run [BUDGET_S]`, which joins the parts, installs them
# under /tmp/site and measures (launch/gpu_physics.py).
set -euo pipefail
cd "$(dirname "$0")/.."
grep -qx '/.ship/' .git/info/exclude 2>/dev/null || echo '/.ship/' >> .git/info/exclude
rm -rf .ship && mkdir -p .ship/wheels
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
  --platform manylinux2014_x86_64 --platform manylinux1_x86_64 -d .ship/wheels \
  mujoco==3.17.0 mujoco-mjx==3.17.0 warp-lang==1.18.0 brax==0.14.2 ml-collections==1.1.0 trimesh==5.2.0 \
  jaxopt==0.8.5 tensorboardx==2.6.5 glfw==2.11.0 pyopengl==3.1.10
tar -cf .ship/ship.tar -C .ship wheels
rm -rf .ship/wheels
split -n 4 -d .ship/ship.tar .ship/ship.tar.
rm .ship/ship.tar
ls -l .ship

#!/usr/bin/env bash
# What the GPU machine (device tool: Python 3.12, torch, no package registry) needs to run the
# factory's stages, gathered here into folders that .gitignore lists and a device call carries:
#
#   .whl   first part of the wheels (under the 64 MiB a call may carry), installed by a first call
#   .whl2  the rest, installed by a second call right after (the machine stays warm 30 s)
#   .gl    the GL loader debs for MUJOCO_GL=egl rendering
#   .gpu/robots  the composed Panda models, fixed and mobile (robosuite's wheel is 148 MB: they are exported
#                here once and read through FACTORY_ROBOT_CACHE instead)
#   .gpu/env.sh  the environment of every later call
#
# The wheel list is what `python -m factory` imports there for generate, demos, dataset, train
# and eval beyond the machine's own packages (checked by importing the policy, dataset and
# lerobot modules in .venv and listing the missing top-level modules: pyserial is one, lerobot's
# motors import it). Use (here, once):
#   bash scripts/experiments/device_bundle.sh
# then, on the device, call 1 (carry .whl):
#   python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --target /tmp/site .whl/*.whl
#   python3 -m pip uninstall -y -q transformers   # needs a newer huggingface_hub than lerobot pins
# and call 2 (carry .whl2 .gl .gpu), started within 30 s of the first:
#   for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig
#   python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --target /tmp/site2 .whl2/*.whl
#   . .gpu/env.sh; python3 -m factory ...   (from the checkout's root: env.sh reads $PWD)
# Copy every result under $OUT in the call that makes it: a machine left idle for 30 s is given
# back with everything on it (this lost two evaluations once).
set -euo pipefail
cd "$(dirname "$0")/../.."
PY=${PY:-.venv/bin/python}
PLAT=""
for p in manylinux_2_35 manylinux_2_34 manylinux_2_31 manylinux_2_28 manylinux_2_27 manylinux_2_24 \
  manylinux_2_17 manylinux2014 manylinux1; do PLAT="$PLAT --platform ${p}_x86_64"; done
pins() {  # pins <names...>: name==version of each as installed in .venv (one interpreter start)
  "$PY" -c 'import sys, importlib.metadata as m; print(*(f"{n}=={m.version(n)}" for n in sys.argv[1:]))' "$@"
}
# Part 1: PyAV (39 MB) and the small pure-Python ones; part 2: MuJoCo, planning, lerobot & co.
PART1="av numcodecs deepdiff dill donfig draccus farama-notifications fast-simplification glfw
  google-crc32c importlib-metadata jsonlines mergedeep multiprocess omegaconf orderly-set plyfile
  pyyaml-include qpsolvers toml typing-inspection pydantic annotated-types platformdirs mink
  termcolor pyserial"
PART2="mujoco mujoco-core ompl diffusers pyopengl rapidfuzz coacd pydantic-core daqp lerobot ruckig
  datasets trimesh rtree zarr gymnasium hydra-core"
fetch() {  # fetch <dir> <names...>: the versions installed in .venv, as Python 3.12 wheels
  local dir=$1; shift; mkdir -p "$dir"
  python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 \
    --implementation cp $PLAT -d "$dir" $(pins "$@")
}
fetch .whl $PART1
fetch .whl2 $PART2
# hydra's parser runtime has no wheel on PyPI: build one (pure Python)
python3 -m pip wheel -q --no-deps -w .whl2 $(pins antlr4-python3-runtime)
mkdir -p .gl /tmp/amd64/partial
o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64'
apt-get $o update -qq
(cd .gl && apt-get $o download libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2)
mkdir -p .gpu
FACTORY_ROBOT_CACHE=$PWD/.gpu/robots "$PY" -c \
  "from factory.robots.panda import export_robot, robot_cache_dir as d; d().is_dir() or export_robot(d())"
FACTORY_ROBOT_CACHE=$PWD/.gpu/robots "$PY" -c "from factory.robots.mobile_panda import \
  export_mobile_robot, mobile_cache_dir as d; d().is_dir() or export_mobile_robot(d())"
cat > .gpu/env.sh <<'EOF'
export PYTHONPATH=/tmp/site:/tmp/site2:$PWD MUJOCO_GL=egl FACTORY_ROBOT_CACHE=$PWD/.gpu/robots \
  PYTHONUNBUFFERED=1 HF_HUB_OFFLINE=1
EOF
du -sh .whl .whl2 .gl .gpu

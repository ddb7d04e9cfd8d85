#!/usr/bin/env bash
# Gathers everything a bare GPU machine (Python 3.12 with its own PyTorch, JAX and numpy, no
# package index) needs to run the factory's stages into ONE tar file, and prints the line that
# installs it there (scripts/gpu_install.sh, which the tar carries too):
#
#   gpu_bundle/wheels/   the wheels below, Python 3.12 manylinux x86_64, the versions installed in
#                        .venv (antlr4's runtime has no wheel on PyPI: built here, pure Python)
#   gpu_bundle/gl/       the GL loader debs for MUJOCO_GL=egl rendering
#   gpu_bundle/robots/   the composed Panda models, fixed and mobile (robosuite's wheel is 148 MB:
#                        they are exported here once and read through FACTORY_ROBOT_CACHE)
#   gpu_bundle/env.sh    the environment for gpu_install.sh's defaults (it writes its own)
#   gpu_bundle/gpu_install.sh, gpu_bundle/WHEELS.txt (name==version per line)
#
# The wheel list is what `python -m factory` imports there for generate, demos, dataset, train
# and eval beyond the machine's own packages (found by importing the policy, dataset and lerobot
# modules in .venv and listing the missing top-level modules: pyserial is one, lerobot's motors
# import it), plus warp-lang, mujoco-warp and mujoco-mjx for the GPU executors and simulation.
#
# Use (from anywhere; paths are relative to the repository root):
#   bash scripts/gpu_bundle.sh                 # gpu_bundle.tar
#   bash scripts/gpu_bundle.sh --split 35M     # gpu_bundle.tar.part00, ... + gpu_bundle.tar.md5
#   bash scripts/gpu_bundle.sh --out /tmp/b.tar
#   bash scripts/gpu_bundle.sh --list          # the pinned wheels, no network
# Downloads are kept in .gpu_bundle_cache/ (wheels, gl, robots): a re-run fetches only what is
# missing there (a changed pin in .venv fetches the new version; nothing else is refetched).
# Environment: PY (default .venv/bin/python, whose versions are pinned), PIP (default
# `python3 -m pip`, any pip that can reach PyPI).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
PY=${PY:-.venv/bin/python}
read -r -a PIP <<<"${PIP:-python3 -m pip}"
CACHE=$ROOT/.gpu_bundle_cache
OUT=$ROOT/gpu_bundle.tar
SPLIT=""
LIST=0

usage() {
  sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'
}
die() { echo "gpu_bundle: $*" >&2; exit 2; }
while [ $# -gt 0 ]; do
  case $1 in
    --out) [ $# -ge 2 ] || die "--out needs a path (e.g. --out /tmp/gpu_bundle.tar)"; OUT=$2; shift 2 ;;
    --out=*) OUT=${1#--out=}; shift ;;
    --split) [ $# -ge 2 ] || die "--split needs a size (e.g. --split 37M)"; SPLIT=$2; shift 2 ;;
    --split=*) SPLIT=${1#--split=}; shift ;;
    --list) LIST=1; shift ;;
    -h|--help) usage; exit 0 ;;
    *) die "unknown argument '$1' (see: bash scripts/gpu_bundle.sh --help)" ;;
  esac
done
case $OUT in /*) ;; *) OUT=$ROOT/$OUT ;; esac
SPLIT_BYTES=""
if [ -n "$SPLIT" ]; then
  SPLIT_BYTES=$(numfmt --from=iec "$SPLIT" 2>/dev/null) && [ "$SPLIT_BYTES" -gt 0 ] ||
    die "--split $SPLIT: not a size (e.g. 37M, 1G, 50000000)"
fi
[ -x "$PY" ] || die "$PY not found: run bash scripts/setup.sh first (its versions are pinned)"

# Part 1 of the old two-call transfer: PyAV (39 MB) and the small pure-Python ones; part 2:
# MuJoCo, planning, lerobot & co.; GPU: Warp (149 MB), MuJoCo Warp, MJX.
WHEELS="av numcodecs deepdiff dill donfig draccus farama-notifications fast-simplification glfw
  google-crc32c importlib-metadata jsonlines mergedeep multiprocess omegaconf orderly-set plyfile
  pyyaml-include qpsolvers toml typing-inspection pydantic annotated-types platformdirs mink
  termcolor pyserial
  mujoco mujoco-core ompl diffusers pyopengl rapidfuzz coacd pydantic-core daqp lerobot ruckig
  datasets trimesh rtree zarr gymnasium hydra-core
  warp-lang mujoco-warp mujoco-mjx"
BUILT="antlr4-python3-runtime"  # no wheel on PyPI: `pip wheel` of its sdist
GL_DEBS="libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2"

# name==version of each as installed in .venv, one a line (one interpreter start)
# shellcheck disable=SC2086
PINS=$("$PY" -c '
import sys, importlib.metadata as m
missing = []
for n in sys.argv[1:]:
    try:
        print(f"{n}=={m.version(n)}")
    except m.PackageNotFoundError:
        missing.append(n)
if missing:
    sys.exit("gpu_bundle: not installed in .venv: " + " ".join(missing) + " (run scripts/setup.sh)")
' $WHEELS $BUILT)
if [ "$LIST" = 1 ]; then
  echo "$PINS"
  exit 0
fi

T0=$SECONDS
mkdir -p "$CACHE/wheels" "$CACHE/gl"
# "pin path" a line: the cached wheel of each pin (wheel names normalise '-' and '.' to '_'),
# or "pin -" where there is none.
cached() {  # cached <name==version...>
  "$PY" - "$CACHE/wheels" "$@" <<'EOF'
import re, sys
from pathlib import Path
names = sorted(p.name for p in Path(sys.argv[1]).glob("*.whl"))
for pin in sys.argv[2:]:
    name, version = pin.split("==")
    stem = (re.sub(r"[-_.]+", "_", name) + "-" + version + "-").lower()
    hits = [n for n in names if n.lower().startswith(stem)]
    print(pin, Path(sys.argv[1], hits[0]) if hits else "-")
EOF
}

# 1. Wheels: only those missing from the cache are fetched.
PLAT=()
for p in manylinux_2_35 manylinux_2_34 manylinux_2_31 manylinux_2_28 manylinux_2_27 manylinux_2_24 \
  manylinux_2_17 manylinux2014 manylinux1; do PLAT+=(--platform "${p}_x86_64"); done
fetch=() build=()
# shellcheck disable=SC2086
while read -r pin f; do
  [ "$f" = - ] || continue
  case " $BUILT " in *" ${pin%%==*} "*) build+=("$pin") ;; *) fetch+=("$pin") ;; esac
done < <(cached $PINS)
if [ ${#fetch[@]} -gt 0 ]; then
  echo "gpu_bundle: downloading ${#fetch[@]} wheels: ${fetch[*]}"
  "${PIP[@]}" download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
    "${PLAT[@]}" -d "$CACHE/wheels" "${fetch[@]}"
fi
if [ ${#build[@]} -gt 0 ]; then
  echo "gpu_bundle: building ${build[*]}"
  "${PIP[@]}" wheel -q --no-deps -w "$CACHE/wheels" "${build[@]}"
fi
files=()
# shellcheck disable=SC2086
while read -r pin f; do
  [ "$f" != - ] || die "no wheel for $pin in $CACHE/wheels after the download"
  files+=("$f")
done < <(cached $PINS)

# 2. GL loader debs (amd64, from this machine's apt sources; lists kept out of /var/lib/apt).
need=()
for d in $GL_DEBS; do compgen -G "$CACHE/gl/${d}_*_amd64.deb" >/dev/null || need+=("$d"); done
if [ ${#need[@]} -gt 0 ]; then
  echo "gpu_bundle: downloading GL debs: ${need[*]}"
  mkdir -p "$CACHE/apt-lists/partial"
  o=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 "-oDir::State::Lists=$CACHE/apt-lists")
  apt-get "${o[@]}" update -qq
  (cd "$CACHE/gl" && apt-get "${o[@]}" download "${need[@]}")
fi

# 3. Robot models, exported once (robosuite's meshes composed into MJCF).
export FACTORY_ROBOT_CACHE=$CACHE/robots
"$PY" -c "from factory.robots.panda import export_robot, robot_cache_dir as d
d().is_dir() or export_robot(d())"
"$PY" -c "from factory.robots.mobile_panda import export_mobile_robot, mobile_cache_dir as d
d().is_dir() or export_mobile_robot(d())"

# 4. The tar: a staging folder of links, dereferenced by tar (nothing is copied twice).
STAGE=$CACHE/stage/gpu_bundle
rm -rf "$CACHE/stage"
mkdir -p "$STAGE/wheels" "$STAGE/gl"
for f in "${files[@]}"; do ln -s "$f" "$STAGE/wheels/"; done
for d in $GL_DEBS; do for f in "$CACHE/gl/${d}"_*_amd64.deb; do ln -s "$f" "$STAGE/gl/"; done; done
ln -s "$CACHE/robots" "$STAGE/robots"
ln -s "$ROOT/scripts/gpu_install.sh" "$STAGE/gpu_install.sh"
echo "$PINS" >"$STAGE/WHEELS.txt"
cat >"$STAGE/env.sh" <<'EOF'
# gpu_install.sh's defaults (it writes this file with its own paths to .gpu/env.sh); source it
# from the repository's root
export PYTHONPATH=/tmp/factory-site:$PWD MUJOCO_GL=egl FACTORY_ROBOT_CACHE=$PWD/.gpu/robots \
  PYTHONUNBUFFERED=1 HF_HUB_OFFLINE=1
EOF
mkdir -p "$(dirname "$OUT")"
rm -f "$OUT" "$OUT".part* "$OUT.md5"
tar -chf "$OUT" -C "$CACHE/stage" --sort=name --owner=0 --group=0 --numeric-owner gpu_bundle
rm -rf "$CACHE/stage"
SIZE=$(stat -c %s "$OUT")
NAME=$(basename "$OUT")
(cd "$(dirname "$OUT")" && md5sum "$NAME") >"$OUT.md5.tmp"
echo "gpu_bundle: $OUT, $(numfmt --to=iec "$SIZE")B ($SIZE bytes): ${#files[@]} wheels," \
  "$(echo "$GL_DEBS" | wc -w) GL debs, robots, gpu_install.sh; $((SECONDS - T0)) s"
REL=$OUT
case $OUT in "$ROOT"/*) REL=${OUT#"$ROOT"/} ;; esac
if [ -n "$SPLIT_BYTES" ]; then
  n=$(((SIZE + SPLIT_BYTES - 1) / SPLIT_BYTES))
  a=2
  [ "$n" -le 100 ] || a=${#n}
  split -b "$SPLIT_BYTES" -d -a "$a" "$OUT" "$OUT.part"
  (cd "$(dirname "$OUT")" && md5sum "$NAME".part*) >>"$OUT.md5.tmp"
  rm -f "$OUT"
  mv "$OUT.md5.tmp" "$OUT.md5"
  echo "gpu_bundle: split into $n parts of at most $SPLIT ($REL.part*), checksums in $REL.md5:"
  (cd "$(dirname "$OUT")" && ls -l "$NAME".part* "$NAME.md5" | awk '{print "  " $5, $9}')
  echo "Copy $REL.part* and $REL.md5 to the GPU machine's checkout root, and there run:"
  echo "  bash scripts/gpu_install.sh $NAME.part* && source .gpu/env.sh"
else
  mv "$OUT.md5.tmp" "$OUT.md5"
  echo "Copy $REL and $REL.md5 to the GPU machine's checkout root, and there run:"
  echo "  bash scripts/gpu_install.sh $NAME && source .gpu/env.sh"
fi

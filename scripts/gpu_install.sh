#!/usr/bin/env bash
# Installs a bundle made by scripts/gpu_bundle.sh on a bare GPU machine (Python 3.12 with its own
# PyTorch, JAX and numpy, no package index). Run it from the repository checkout's root:
#
#   bash scripts/gpu_install.sh gpu_bundle.tar            # the whole tar
#   bash scripts/gpu_install.sh gpu_bundle.tar.part*      # or its pieces (--split), in any order
#   source .gpu/env.sh                                     # then: python3 -m factory ...
#
# It checks the md5 of what it is given where gpu_bundle.tar.md5 lies beside it, installs the
# wheels with pip --no-index --no-deps into --target (default /tmp/factory-site), uninstalls the
# machine's transformers (it needs a newer huggingface_hub than lerobot pins), unpacks the GL
# loader debs into / and runs ldconfig when run as root (skipped otherwise), places the robot
# models and writes the env file (PYTHONPATH=<target>:<checkout>, MUJOCO_GL=egl,
# FACTORY_ROBOT_CACHE, PYTHONUNBUFFERED=1, HF_HUB_OFFLINE=1).
#
# Options: --target DIR (site folder, default /tmp/factory-site), --env FILE (default
# .gpu/env.sh), --robots DIR (default .gpu/robots), --keep-transformers, --no-gl.
# Environment: PYTHON (default python3).
set -euo pipefail
T0=$(date +%s.%N)
since() { awk -v a="$1" -v b="$(date +%s.%N)" 'BEGIN {printf "%.1f", b - a}'; }
PYTHON=${PYTHON:-python3}
TARGET=/tmp/factory-site
ENVFILE=.gpu/env.sh
ROBOTS=.gpu/robots
KEEP_TRANSFORMERS=0
GL=1
ME="bash scripts/gpu_install.sh"

usage() { sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; }
die() { echo "gpu_install: $*" >&2; exit "${2:-1}"; }
files=()
while [ $# -gt 0 ]; do
  case $1 in
    --target|--env|--robots)
      [ $# -ge 2 ] || die "$1 needs a value (see: $ME --help)" 2
      case $1 in --target) TARGET=$2 ;; --env) ENVFILE=$2 ;; --robots) ROBOTS=$2 ;; esac
      shift 2 ;;
    --target=*) TARGET=${1#*=}; shift ;;
    --env=*) ENVFILE=${1#*=}; shift ;;
    --robots=*) ROBOTS=${1#*=}; shift ;;
    --keep-transformers) KEEP_TRANSFORMERS=1; shift ;;
    --no-gl) GL=0; shift ;;
    -h|--help) usage; exit 0 ;;
    --) shift; files+=("$@"); break ;;
    -*) die "unknown option '$1' (see: $ME --help)" 2 ;;
    *) files+=("$1"); shift ;;
  esac
done
[ ${#files[@]} -gt 0 ] ||
  die "no bundle given: $ME gpu_bundle.tar (or gpu_bundle.tar.part*), made by scripts/gpu_bundle.sh" 2
for f in "${files[@]}"; do
  [ -f "$f" ] || die "no such file: $f (make it with 'bash scripts/gpu_bundle.sh [--split 37M]'\
 on a machine with PyPI access and copy it here)"
done
[ -d factory ] || die "run from the repository checkout's root (the folder holding factory/), not $PWD"
command -v "$PYTHON" >/dev/null || die "$PYTHON not found (set PYTHON=...)"
abspath() { case $1 in /*) echo "$1" ;; *) echo "$PWD/$1" ;; esac; }
TARGET=$(abspath "$TARGET") ENVFILE=$(abspath "$ENVFILE") ROBOTS=$(abspath "$ROBOTS")

# Pieces in name order (part00, part01, ...), whatever order the shell gave them in.
mapfile -t files < <(printf '%s\n' "${files[@]}" | sort)

# 1. Checksums: BUNDLE.md5 beside the tar or its pieces lists each piece and the whole tar.
first=${files[0]}
base=$(echo "$first" | sed -E 's/\.part[0-9]+$//')
if [ -f "$base.md5" ]; then
  given=$(for f in "${files[@]}"; do basename "$f"; done)
  if echo "$given" | grep -qE '\.part[0-9]+$'; then
    for p in $(awk '$2 ~ /\.part[0-9]+$/ {print $2}' "$base.md5"); do
      echo "$given" | grep -qxF "$p" ||
        die "piece $p is missing: give all of $base.part* (they are listed in $base.md5)"
    done
  fi
  for f in "${files[@]}"; do
    want=$(awk -v n="$(basename "$f")" '$2 == n {print $1}' "$base.md5")
    [ -n "$want" ] || die "$(basename "$f") is not listed in $base.md5: a piece of another bundle?"
    got=$(md5sum "$f" | awk '{print $1}')
    [ "$got" = "$want" ] ||
      die "md5 of $f is $got, $base.md5 says $want: copy it again (or make the bundle again)"
  done
  echo "gpu_install: md5 of ${#files[@]} file(s) checked against $base.md5"
else
  echo "gpu_install: no $base.md5 beside the bundle: checksums not checked"
fi

# 2. Unpack (pieces concatenated on the fly).
WORK=$(mktemp -d "${TMPDIR:-/tmp}/factory-bundle.XXXXXX")
trap 'rm -rf "$WORK"' EXIT
cat "${files[@]}" | tar -x -C "$WORK" ||
  die "could not unpack ${files[*]}: not a bundle of scripts/gpu_bundle.sh, or a piece is missing"
B=$WORK/gpu_bundle
[ -d "$B/wheels" ] || die "no gpu_bundle/wheels in ${files[*]}: not a bundle of scripts/gpu_bundle.sh"

# 3. Wheels (--upgrade: a second install into the same target replaces what is there).
wheels=("$B"/wheels/*.whl)
T1=$(date +%s.%N)
mkdir -p "$TARGET"
"$PYTHON" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
  --target "$TARGET" "${wheels[@]}"
echo "gpu_install: ${#wheels[@]} wheels into $TARGET in $(since "$T1") s"
if [ "$KEEP_TRANSFORMERS" = 0 ] && "$PYTHON" -m pip show -q transformers >/dev/null 2>&1; then
  if "$PYTHON" -m pip uninstall -y -q transformers; then
    echo "gpu_install: uninstalled transformers (it needs a newer huggingface_hub than lerobot pins)"
  else
    echo "gpu_install: could not uninstall transformers, which needs a newer huggingface_hub than" \
      "lerobot pins: run $PYTHON -m pip uninstall -y transformers" >&2
  fi
fi

# 4. GL loaders for MUJOCO_GL=egl.
debs=()
[ -d "$B/gl" ] && debs=("$B"/gl/*.deb)
[ -e "${debs[0]:-}" ] || debs=()
if [ "$GL" = 0 ]; then
  echo "gpu_install: --no-gl: GL loader debs not unpacked"
elif [ ${#debs[@]} -eq 0 ]; then
  echo "gpu_install: no GL loader debs in the bundle"
elif [ "$(id -u)" != 0 ]; then
  echo "gpu_install: not root: ${#debs[@]} GL loader debs not unpacked (EGL rendering needs them;" \
    "run as root, or install libegl1 libgl1 libgles2 libopengl0)"
else
  for d in "${debs[@]}"; do dpkg -x "$d" /; done
  ldconfig
  echo "gpu_install: ${#debs[@]} GL loader debs unpacked into /, ldconfig run"
fi

# 5. Robot models and the env file.
if [ -d "$B/robots" ]; then
  mkdir -p "$ROBOTS"
  cp -a "$B/robots/." "$ROBOTS/"
  echo "gpu_install: robot models in $ROBOTS"
fi
mkdir -p "$(dirname "$ENVFILE")"
cat >"$ENVFILE" <<EOF
# written by scripts/gpu_install.sh: source it before python3 -m factory ...
export PYTHONPATH=$TARGET:$PWD MUJOCO_GL=egl FACTORY_ROBOT_CACHE=$ROBOTS \\
  PYTHONUNBUFFERED=1 HF_HUB_OFFLINE=1
EOF
echo "gpu_install: done in $(since "$T0") s; now run:"
echo "source $ENVFILE"

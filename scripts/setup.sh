#!/usr/bin/env bash
# Sets up factory on a fresh Debian/Ubuntu machine, idempotently:
#   1. system libraries for offscreen rendering (Mesa EGL and OSMesa) and Chromium, via apt-get;
#   2. a virtual environment in .venv with factory and all its dependencies (extras all,dev).
# A second run with an unchanged pyproject.toml takes seconds.
# Environment: PYTHON (default python3, >= 3.11), FACTORY_SKIP_APT=1 to skip step 1,
#   FACTORY_CUDA=1/0: install the parts of PyTorch's CUDA stack that a CPU-only machine never
#   loads, or not (default: only where nvidia-smi lists a GPU; scripts/cpu-overrides.txt).
# Packages are installed with uv (from PyPI, into .venv): its overrides can drop requirements
# (pip cannot), and it links files from its cache instead of keeping downloaded archives as pip
# does, so the disk holds the environment about once (about 10 GB, most of it PyTorch and its
# CUDA libraries). Its cache is .venv/.uv-cache (same file system, so links work) unless
# UV_CACHE_DIR says otherwise. Modules are compiled to bytecode at install, as pip does: without
# it every process compiles torch's and lerobot's sources again where PYTHONDONTWRITEBYTECODE is
# set (importing lerobot's dataset module took 11 s instead of 5 s).
set -euo pipefail
cd "$(dirname "$0")/.."

PY=${PYTHON:-python3}
if ! "$PY" -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
  echo "setup: factory needs Python >= 3.11; $PY is $("$PY" --version 2>&1). Set PYTHON=..." >&2
  exit 1
fi

# 1. System packages (headless OpenGL for MuJoCo's renderer; Chromium for the report's browser
#    test, tests/report, driven by playwright without a browser download).
SYSTEM_PACKAGES=(libegl1 libegl-mesa0 libgl1-mesa-dri libgles2 libosmesa6 libglu1-mesa chromium)
if [ "${FACTORY_SKIP_APT:-0}" != 1 ] && command -v apt-get >/dev/null 2>&1; then
  missing=()
  for p in "${SYSTEM_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    SUDO=""
    [ "$(id -u)" = 0 ] || SUDO="sudo"
    echo "setup: installing system packages: ${missing[*]}"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
  fi
fi

# 2. Python environment.
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv with $("$PY" --version)"
  "$PY" -m venv .venv
fi
stamp=.venv/.factory-setup
cuda=${FACTORY_CUDA:-}
if [ -z "$cuda" ]; then
  cuda=0
  if command -v nvidia-smi >/dev/null 2>&1 && nvidia-smi -L 2>/dev/null | grep -q GPU; then cuda=1; fi
fi
want=$( (cat pyproject.toml scripts/setup.sh scripts/cpu-overrides.txt; echo "cuda=$cuda") \
  | sha256sum | cut -d' ' -f1)
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "setup: installing factory[all,dev] into .venv (first time: a few minutes)"
  .venv/bin/python -m pip install --disable-pip-version-check -q "uv>=0.5"
  overrides=()
  [ "$cuda" = 1 ] || overrides=(--override scripts/cpu-overrides.txt)
  UV_CACHE_DIR=${UV_CACHE_DIR:-.venv/.uv-cache} UV_LINK_MODE=${UV_LINK_MODE:-hardlink} \
    .venv/bin/uv pip install --python .venv/bin/python -q --compile-bytecode "${overrides[@]}" \
    -e ".[all,dev]"
  echo "$want" > "$stamp"
fi
echo "setup: ready (.venv/bin/python -m factory --help)"

#!/usr/bin/env bash
# The GPU factory's checks on one GPU machine, after scripts/gpu_install.sh, in order of worth
# (a session's device time may end before the last):
#
#   1. scripts/bench_demos.py at its GPU defaults (8 generated kitchens x 1,536 episodes) with an
#      empty kernel cache: the bare-machine rate, time to the first stored episode (the kitchens
#      are generated first unless BENCH_RUN holds them: carry a run folder made beforehand with
#      `python -m factory stage=generate run_dir=runs/bench_demos8 "generate.prompts=[a kitchen
#      where the robot picks up a mug and puts it in the bowl]" generate.scenes_per_prompt=8
#      generate.render=false`, the same kitchens bench_demos.py generates);
#   2. pytest -m gpu (the cache of step 1 is kept: kernels it compiled are not compiled again);
#   3. scripts/experiments/gpu_soak.py on the kitchens of step 1 (kill -9 after the first GPU
#      call, read back, re-run).
#
# Use (repository root; run it in the background and watch LOG):
#   source .gpu/env.sh; bash scripts/experiments/gpu_factory_checks.sh DIR [STEPS]
# DIR gets bench.json, soak.json, pytest.log and a log per step (the bench's episodes are deleted
# after it, its JSON kept: the soak needs the disk); STEPS is a subset of
# "bench gpu soak" (default all three). Environment: CACHE (kernel cache, default
# /tmp/warpcache, emptied before step 1), BENCH_RUN (the bench's run folder, default
# runs/bench_demos), BENCH_ARGS (more bench_demos.py arguments, e.g. "--scenes 3"),
# SOAK_SCENES (default 3), SOAK_EPISODES (default 1536).
set -u
DIR=${1:?a folder for the results}
STEPS=${2:-bench gpu soak}
CACHE=${CACHE:-/tmp/warpcache}
BENCH_RUN=${BENCH_RUN:-runs/bench_demos}
mkdir -p "$DIR"
card=$(nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null | head -1)
echo "gpu_factory_checks: $card; steps: $STEPS; kernel cache $CACHE" | tee "$DIR/steps.log"
stamp() { echo "$(date -u +%H:%M:%S) $*" | tee -a "$DIR/steps.log"; }
for step in $STEPS; do
  case $step in
    bench)
      rm -rf "$CACHE"
      stamp "bench: start (empty kernel cache)"
      python3 scripts/bench_demos.py --executor warp --kernel-cache "$CACHE" \
        --run-dir "$BENCH_RUN" ${BENCH_ARGS:-} --out "$DIR/bench.json" >"$DIR/bench.log" 2>&1
      stamp "bench: rc=$?"
      # its episodes (about 55 GB at the defaults) would leave the soak no room on a 64 GiB disk
      rm -rf "$BENCH_RUN/episodes"
      stamp "bench: episodes deleted ($(df -h --output=avail "$BENCH_RUN" | tail -1 | tr -d ' ') free)" ;;
    gpu)
      stamp "pytest -m gpu: start"
      WARP_CACHE_PATH=$CACHE python3 -m pytest -m gpu -q -p no:cacheprovider -ra \
        --durations=15 >"$DIR/pytest.log" 2>&1
      stamp "pytest -m gpu: rc=$? $(tail -1 "$DIR/pytest.log")" ;;
    soak)
      mkdir -p runs/soak
      # the bench's first SOAK_SCENES kitchens (the stage records every scene of its run)
      if [ -d "$BENCH_RUN/scenes" ] && [ ! -d runs/soak/scenes ]; then
        mkdir -p runs/soak/scenes
        for sc in $(ls "$BENCH_RUN/scenes" | sort | head -n "${SOAK_SCENES:-3}"); do
          cp -r "$BENCH_RUN/scenes/$sc" runs/soak/scenes/
        done
        [ -d "$BENCH_RUN/assets" ] && cp -r "$BENCH_RUN/assets" runs/soak/
      fi
      stamp "soak: start"
      python3 scripts/experiments/gpu_soak.py --scenes "${SOAK_SCENES:-3}" \
        --episodes "${SOAK_EPISODES:-1536}" --kill-after-calls 1 --kernel-cache "$CACHE" \
        --out "$DIR/soak.json" >"$DIR/soak.log" 2>&1
      stamp "soak: rc=$?" ;;
    *) stamp "unknown step '$step' (bench, gpu, soak)" ;;
  esac
done
stamp "done"

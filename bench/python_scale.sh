#!/usr/bin/env bash
# Ray with 1 and 2 local workers over the same 200 synthesised 640×480 camera scenes (issue 46),
# each worker one core (RAYON_NUM_THREADS=1), the detector built once per worker. Times are the
# example's own (from the first batch handed out to the last result back; not Ray's start-up).
# Needs a venv with ray[data] and the package built in release (scripts/test-python.sh's venv,
# then `cd python && maturin develop --release`) and a release CLI to draw the scenes:
#   cargo build --release && bench/python_scale.sh [RUNS]
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-3}
T=${TAGSMITH:-target/release/tagsmith}
py=${PYTHON:-target/python-venv/bin/python}
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
"$T" synth apriltag-36h11 --mode camera --width 640 --height 480 -n 200 --seed 4600 -o "$dir/scenes" >/dev/null
rm -f "$dir"/scenes/contact*
echo "$(ls "$dir"/scenes/*.png | wc -l) images; $runs runs of each, alternating"
for run in $(seq "$runs"); do
  for workers in 1 2; do
    line=$(RAY_DISABLE_USAGE_STATS=1 "$py" python/examples/ray_detect.py "$dir/scenes" \
      -o "$dir/out-$workers.jsonl" --workers "$workers" --batch-size 8 2>/dev/null | tail -1)
    echo "run $run, $workers worker(s): $line"
  done
done

#!/usr/bin/env bash
# Pose accuracy side by side on the evaluation harness: AprilTag 3 and OpenCV ArUco on whole images,
# Tagsmith stage 2 from ROIs moved by ±5 % of the side with each --refine mode. One run, the same
# images for every detector. Needs bench/.venv (bench/setup.sh) and a release build.
#
#   cargo build --release && bench/poses.sh /tmp/poses
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: bench/poses.sh OUT_DIR}
T=target/release/tagsmith
PY=bench/.venv/bin/python
mkdir -p "$out"
for family in apriltag-36h11 apriltag-xo-36h11; do
  set_dir="$out/$family"
  [ -f "$set_dir/set.json" ] || $T eval generate "$family" -o "$set_dir"
  if [ "$family" = apriltag-36h11 ]; then
    for d in apriltag opencv; do
      $PY bench/baselines.py "$set_dir" --detector $d -o "$out/$family-$d.json"
    done
  fi
  for mode in none keypoints full; do
    $T detect-set "$set_dir" --refine $mode -o "$out/$family-tagsmith-$mode.json"
  done
  for f in "$out/$family"-*.json; do
    name=$(basename "$f" .json)
    echo "== $name"
    $T eval score "$set_dir" "$f" -o "$out/report-$name" | grep -E '^\| (normal|difficult|jitter)'
    grep 'Jitter over' "$out/report-$name/report.md"
    $PY bench/percentiles.py "$set_dir" "$f"
  done
done

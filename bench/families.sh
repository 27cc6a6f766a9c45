#!/usr/bin/env bash
# Every family that detects with shipped weights (`tagsmith families`: default or named) on a
# fresh set of its own, beside the baseline that reads it where one does, in one run (issue 45):
# one row per family with Normal, Difficult and the noise sweep, precision, and Tagsmith's
# Difficult recall against the baseline's on the same markers with the paired 95 % interval.
# Needs bench/.venv (bench/setup.sh) and a release build:
#   cargo build --release && bench/families.sh OUT_DIR [SEED] [PER_CELL]
# PER_CELL=20 gives 700 Normal and 1300 Difficult markers per family (≈ 6 minutes a family here);
# FAMILIES="a b" picks some. Baselines: bench/side_by_side.sh (AprilTag 3 for the AprilTag
# families it has, OpenCV for the dictionaries it has); a family no baseline reads gets Tagsmith's
# rows beside the DeepTag paper's own Normal / Difficult recall where the paper has a row for it
# (Zhang et al., TPAMI 2023, the table of its own dataset: another protocol and other images, so
# a reference, not a paired comparison).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: bench/families.sh OUT_DIR [SEED] [PER_CELL]}
seed=${2:-9191}
per_cell=${3:-20}
T=${TAGSMITH:-target/release/tagsmith}
PY=bench/.venv/bin/python
families=${FAMILIES:-$($T families | awk 'NR > 1 && ($7 == "default" || $7 == "named") { print $1 }')}
mkdir -p "$out"

# The DeepTag paper's recall for a family no baseline here reads, "Normal / Difficult".
paper() {
  case "$1" in
    topotag-like) echo "DeepTag (paper) 100 % / 59.86 %" ;;
    apriltag-xo-36h11) echo "DeepTag (paper) 99.97 % / 65.94 %" ;;
    apriltag-xa-36h11) echo "DeepTag (paper) 100 % / 64.57 %" ;;
    runetag | runetag-plus) echo "DeepTag (paper) 65.49 % / 0.75 %" ;;
    *) echo "" ;;
  esac
}

# The recall and precision of a scored row, "recall / precision".
row() { grep -E "^\| $2" "$1" | head -1 | awk -F'|' '{ gsub(/ /, "", $5); gsub(/ /, "", $6); print $5 " / " $6 }'; }

echo "| family | baseline | Normal (recall / precision) | Difficult | noise sweep | Difficult, baseline | Tagsmith − baseline (95 % interval) |"
echo "|---|---|---|---|---|---|---|"
for family in $families; do
  set_dir="$out/$family"
  [ -f "$set_dir/set.json" ] ||
    $T eval generate "$family" --seed "$seed" --per-cell "$per_cell" -o "$set_dir" >/dev/null
  if [ -n "$($PY bench/baselines.py --detectors "$family")" ]; then
    ROWS='normal|difficult|noise' bench/side_by_side.sh "$set_dir" "$out/$family" >"$out/$family.log"
    base=$(ls "$out/$family"-report-apriltag/report.md 2>/dev/null || ls "$out/$family"-report-opencv/report.md)
    name=$(basename "$(dirname "$base")" | sed "s/^$family-report-//")
    # The recall row of the paired comparison, which follows its heading (pose rows come after).
    paired=$(awk -F'|' '/^== Tagsmith \(A\) vs/ { on = 1 } on && /^\| difficult/ {
      gsub(/^ +| +$/, "", $8); gsub(/^ +| +$/, "", $9); print $8 " (" $9 ")"; exit }' "$out/$family.log")
    base_row=$(row "$base" difficult)
  else
    $T detect-set "$set_dir" --full -o "$out/$family-tagsmith.json" >/dev/null
    $T eval score "$set_dir" "$out/$family-tagsmith.json" -o "$out/$family-report-tagsmith" >/dev/null
    name="none" paired="" base_row="$(paper "$family")"
  fi
  ours="$out/$family-report-tagsmith/report.md"
  echo "| $family | $name | $(row "$ours" normal) | $(row "$ours" difficult) | $(row "$ours" 'noise sweep') | $base_row | $paired |"
done

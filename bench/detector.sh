#!/usr/bin/env bash
# The full detector side by side with AprilTag 3 and OpenCV ArUco on whole images (issue 12):
#  1. the evaluation harness (paper protocol: Normal, Difficult, noise and motion-blur sweeps) for
#     AprilTag 36h11 and ArUco 6x6_250 — Tagsmith's stage 1 + stage 2 (`detect-set --full`);
#  2. false positives on 200 marker-free scenes (every family with shipped weights at once);
#  3. speed on 640×480 and 1280×960 images with one marker, stage split included.
# One run, the same images for every detector. Needs bench/.venv (bench/setup.sh) and a release
# build:   cargo build --release && bench/detector.sh /tmp/detector
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: bench/detector.sh OUT_DIR}
T=target/release/tagsmith
PY=bench/.venv/bin/python
mkdir -p "$out"

for family in apriltag-36h11 aruco-6x6_250; do
  set_dir="$out/$family"
  [ -f "$set_dir/set.json" ] || $T eval generate "$family" -o "$set_dir" >/dev/null
  # Every detector, scored, then Tagsmith against the family's own baseline marker by marker: the
  # markers each reads alone and a 95 % interval of the difference (65 Difficult markers: 1.5
  # points each).
  TAGSMITH=$T ROWS='normal|difficult|noise|motion' bench/side_by_side.sh "$set_dir" "$out/$family"
done

echo "== false positives: 200 marker-free 640×480 scenes"
empty="$out/empty"
[ -d "$empty" ] || $T synth apriltag-36h11 --mode camera --width 640 --height 480 --markers 0 \
  -n 200 --seed 77 -o "$empty" >/dev/null
$T detect "$empty"/[0-9]*.png --json "$out/empty-tagsmith.json" | tail -n +1 | grep -v ": 0 markers" || true
$PY - "$out/empty-tagsmith.json" <<'PY'
import json, sys
f = json.load(open(sys.argv[1]))
print(f"Tagsmith (all shipped families): {sum(len(i['detections']) for i in f['images'])} detections in {len(f['images'])} images")
PY
$PY bench/images.py "$empty" --detector apriltag --family apriltag-36h11 -o "$out/empty-apriltag.json"
$PY bench/images.py "$empty" --detector opencv --family aruco-6x6_250 -o "$out/empty-opencv.json"

for size in 640x480 1280x960; do
  w=${size%x*}; h=${size#*x}
  speed="$out/speed-$size"
  [ -d "$speed" ] || $T synth apriltag-36h11 --mode camera --width $w --height $h --markers 1 \
    -n 40 --seed 5 -o "$speed" >/dev/null
  echo "== speed $size, one marker, 40 images (median)"
  $T detect "$speed"/[0-9]*.png --sequential --family apriltag-36h11 --json "$out/speed-$size-tagsmith.json" \
    | $PY -c '
import re, statistics, sys
rows = [re.search(r"markers? .*in (\d+) ms \(propose ([\d.]+) ms, verify ([\d.]+) ms, read ([\d.]+) ms, reconcile [\d.]+ ms; (\d+) ROIs? \(\d+ turned away\), (\d+) stage-2 pass", l) for l in sys.stdin]
rows = [tuple(map(float, r.groups())) for r in rows if r]
print("Tagsmith: median %.0f ms (propose %.1f ms, verify %.1f ms, read %.1f ms), median %d ROIs, %d stage-2 passes" % tuple(
    statistics.median(r[i] for r in rows) for i in range(6)))'
  $PY bench/images.py "$speed" --detector apriltag --family apriltag-36h11 -o "$out/speed-$size-apriltag.json"
  $PY bench/images.py "$speed" --detector opencv --family apriltag-36h11 -o "$out/speed-$size-opencv.json"
done

#!/usr/bin/env bash
# Two builds of `tagsmith detect --sequential` (default families unless FAMILY is set) on the
# same images, runs alternated: per image the median time of each over ROUNDS runs, their ratio,
# stage-2 passes and the markers each reports (and whether the lists match).
#   bench/ab_detect.sh BEFORE_BIN AFTER_BIN IMAGE... [ROUNDS=5 FAMILY="apriltag-36h11 aruco-6x6_250"]
set -euo pipefail
before=${1:?usage: bench/ab_detect.sh BEFORE_BIN AFTER_BIN IMAGE...}
after=${2:?usage: bench/ab_detect.sh BEFORE_BIN AFTER_BIN IMAGE...}
shift 2
rounds=${ROUNDS:-5}
family=()
for f in ${FAMILY:-}; do family+=(--family "$f"); done
for image in "$@"; do
  for _ in $(seq "$rounds"); do
    for bin in "$before" "$after"; do
      echo "$bin	$("$bin" detect --sequential ${family[@]+"${family[@]}"} "$image" 2>&1 | tail -1)"
    done
  done | python3 -c '
import re, statistics, sys
image, before, after = sys.argv[1:4]
runs = {before: [], after: []}
for line in sys.stdin:
    bin, text = line.rstrip("\n").split("\t", 1)
    ms = float(re.search(r" in ([0-9.]+) ms", text).group(1))
    passes = re.search(r"([0-9]+) stage-2 passes", text).group(1)
    found = re.search(r": ([0-9]+) markers? \((.*?)\) in ", text)
    markers = (found.group(1), sorted(found.group(2).split(", "))) if found else ("0", [])
    runs[bin].append((ms, passes, markers))
(a, b) = (runs[before], runs[after])
ma, mb = statistics.median(r[0] for r in a), statistics.median(r[0] for r in b)
same = "same markers" if a[0][2] == b[0][2] else "markers differ"
name = image.rsplit("/", 1)[-1]
print(f"{name}\t{ma:.1f} ms -> {mb:.1f} ms ({mb / ma:.3f})\tpasses {a[0][1]} -> {b[0][1]}\tmarkers {a[0][2][0]} -> {b[0][2][0]}, {same}")
' "$image" "$before" "$after"
done

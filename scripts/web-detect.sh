#!/usr/bin/env bash
# Detection in the browser: serves app/dist (scripts/build-web.sh), opens the studio in headless
# Chromium on the Detect panel with a shipped sample, prints the detector's own timing line and
# writes a screenshot. Repeats RUNS times (fresh page each) for a median.
#   scripts/web-detect.sh OUT.png [SAMPLE] [RUNS]
# Needs Debian's chromium and Node.js; `npm ci --prefix scripts/browser` once (playwright-core,
# which drives the installed chromium and downloads no browser).
set -euo pipefail
out=$(realpath -m "${1:?usage: scripts/web-detect.sh OUT.png [SAMPLE] [RUNS]}")
sample=${2:-aruco-6x6_250-tutorial.jpg}
runs=${3:-1}
port=${PORT:-8766}
root=$(cd "$(dirname "$0")/.." && pwd)
source "$root/scripts/browser/serve.sh"
need_playwright
serve_dist "$port"
for run in $(seq "$runs"); do
  node "$root/scripts/browser/detect.mjs" "http://127.0.0.1:$port/#detect=$sample" "$out"
done
echo "wrote $out"

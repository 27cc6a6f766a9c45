#!/usr/bin/env bash
# The Compare panel in the browser: serves app/dist (scripts/build-web.sh), opens the studio in
# headless Chromium running a comparison of FAMILIES (built-ins with shipped weights, comma-
# separated) over the panel's default scenario with SCENES scenes per swept value, in its web
# worker; prints the run's time and the frames the page drew meanwhile, and writes a screenshot.
#   scripts/web-compare.sh OUT.png [FAMILIES] [SCENES]
# Needs what scripts/web-detect.sh needs.
set -euo pipefail
out=$(realpath -m "${1:?usage: scripts/web-compare.sh OUT.png [FAMILIES] [SCENES]}")
families=${2:-apriltag-36h11,apriltag-xo-36h11}
scenes=${3:-2}
port=${PORT:-8767}
root=$(cd "$(dirname "$0")/.." && pwd)
source "$root/scripts/browser/serve.sh"
need_playwright
serve_dist "$port"
node "$root/scripts/browser/compare.mjs" "http://127.0.0.1:$port/#compare=$families&scenes=$scenes" "$out"
echo "wrote $out"

#!/usr/bin/env bash
# Where the browser's detection spends its time: serves app/dist, detects a shipped sample twice
# in headless Chromium and prints the detection worker's functions by self time during the
# second (the DevTools protocol's sampling profiler, every 100 µs).
#   scripts/build-web.sh --names && scripts/web-profile.sh [SAMPLE] [TOP]
# Without --names the wasm functions appear as numbers. Needs what scripts/web-detect.sh needs.
set -euo pipefail
sample=${1:-aruco-6x6_250-tutorial.jpg}
top=${2:-30}
port=${PORT:-8767}
root=$(cd "$(dirname "$0")/.." && pwd)
source "$root/scripts/browser/serve.sh"
need_playwright
serve_dist "$port"
node "$root/scripts/browser/profile.mjs" "http://127.0.0.1:$port/#detect=$sample" "$top"

# Sourced by the browser checks (scripts/web-*.sh): `serve_dist PORT` serves the web build
# (app/dist, from scripts/build-web.sh) on 127.0.0.1:PORT until the calling script exits, and
# returns once it answers; `need_playwright` installs scripts/browser's pinned playwright-core
# the first time (it drives the installed chromium and downloads no browser).

browser_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)

serve_dist() {
  local port=$1
  [[ -f "$browser_root/app/dist/index.html" ]] ||
    { echo "app/dist is missing: run scripts/build-web.sh first" >&2; exit 2; }
  python3 -m http.server "$port" --bind 127.0.0.1 -d "$browser_root/app/dist" >/dev/null 2>&1 &
  served_by=$!
  trap 'kill $served_by 2>/dev/null || true' EXIT
  for _ in $(seq 50); do curl -sf "http://127.0.0.1:$port/" >/dev/null && break; sleep 0.1; done
}

need_playwright() {
  [[ -d "$browser_root/scripts/browser/node_modules/playwright-core" ]] ||
    npm ci --prefix "$browser_root/scripts/browser" --no-audit --no-fund >/dev/null
}

#!/usr/bin/env bash
# Build the documentation site and take screenshots of its home page and observation page with
# headless Chromium, into docs/images/screenshots/. Needs the docs extra and chromium
# (Debian: apt-get install -y chromium). Usage: docs/tools/docs_screenshots.sh [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/../.."
out="${1:-docs/images/screenshots}"
browser="${CHROMIUM:-$(command -v chromium || command -v chromium-browser || command -v google-chrome || true)}"
if [ -z "$browser" ]; then
    echo "docs_screenshots.sh: no chromium found; install it (apt-get install -y chromium) or set CHROMIUM" >&2
    exit 2
fi
python3 -m mkdocs build --strict --quiet
mkdir -p "$out"
profile="$(mktemp -d)"
trap 'rm -rf "$profile"' EXIT
shoot() {  # shoot PAGE_PATH PNG
    "$browser" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
        --disable-background-networking --disable-component-update --disable-sync \
        --hide-scrollbars --user-data-dir="$profile" --window-size=1280,900 \
        --screenshot="$2" "file://$PWD/site/$1" 2>/dev/null
    echo "$2"
}
shoot index.html "$out/home.png"
shoot environment/observations/index.html "$out/observations.png"

#!/usr/bin/env bash
# The viewer in a real browser: installs Debian's chromium if missing and the test's npm
# package (playwright-core), installs `tissue` with `cargo install` into target/ and starts
# the installed binary's `tissue view` from an empty folder (the page and three.js come from
# the binary), and runs viewer/tests/browser.test.mjs in headless Chromium (WebGL 2 through
# SwiftShader) on the printed URL with its session token.
# Finally checks that closing the page left the server running. Well under 3 minutes.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD

if ! command -v chromium >/dev/null 2>&1 && [ ! -x /usr/bin/chromium ]; then
    echo "browser-test: installing Debian's chromium"
    export DEBIAN_FRONTEND=noninteractive
    apt-get install -y -q chromium >/dev/null 2>&1 \
        || { apt-get update -q >/dev/null && apt-get install -y -q chromium >/dev/null; }
fi
if [ ! -d viewer/node_modules/playwright-core ]; then
    bash scripts/setup-viewer.sh >/dev/null
fi
SECONDS=0
OUT="$ROOT/target/browser-test"
# --target-dir reuses the release build; --force replaces an earlier install.
cargo install --quiet --locked --force --path crates/tissue-cli --root "$OUT/install" \
    --target-dir "$ROOT/target"
echo "browser-test: build and install ${SECONDS} s"
SECONDS=0

mkdir -p "$OUT"
LOG="$OUT/server.log"
EMPTY=$(mktemp -d)
(cd "$EMPTY" && exec env -u TISSUE_VIEWER_DIR "$OUT/install/bin/tissue" view \
    "$ROOT/scenes/liver-probe.toml" --port 0) >"$LOG" 2>&1 &
SERVER=$!
trap 'kill "$SERVER" 2>/dev/null || true; wait "$SERVER" 2>/dev/null || true; rmdir "$EMPTY" 2>/dev/null || true' EXIT

URL=""
for _ in $(seq 1 300); do
    URL=$(grep -o 'http://[0-9.]*:[0-9]*/?token=[0-9a-f]*' "$LOG" | head -n1 || true)
    [ -n "$URL" ] && break
    if ! kill -0 "$SERVER" 2>/dev/null; then cat "$LOG"; echo "browser-test: the server died"; exit 1; fi
    sleep 0.1
done
[ -n "$URL" ] || { cat "$LOG"; echo "browser-test: no URL printed"; exit 1; }
echo "browser-test: $URL"

status=0
timeout 150 node viewer/tests/browser.test.mjs "$URL" "$OUT/screenshot.png" | tee "$OUT/page.log" \
    || status=$?
passed=$(grep -c '^ok ' "$OUT/page.log" || true)
failed=$(grep -c '^FAIL' "$OUT/page.log" || true)
# The page test died before its own verdict (timeout, crash): count that as a failure.
if [ "$status" != 0 ] && [ "$failed" = 0 ]; then failed=1; fi

# Closing the page must not stop the server.
if kill -0 "$SERVER" 2>/dev/null && curl -fsS -o /dev/null "$URL"; then
    echo "ok   server still serving after the page closed"; passed=$((passed + 1))
else
    echo "FAIL server gone after the page closed"; status=1; failed=$((failed + 1))
fi
if grep -q "rejected a message" "$LOG"; then
    echo "ok   rejections logged by the server"; passed=$((passed + 1))
else
    echo "FAIL no rejection in the server log"; status=1; failed=$((failed + 1))
fi
[ "$status" = 0 ] || { echo "--- server log"; tail -n 30 "$LOG"; }
[ "$failed" = 0 ] || status=1
echo "browser-test: page and checks ${SECONDS} s"
echo "browser: $passed passed, $failed failed"
exit "$status"

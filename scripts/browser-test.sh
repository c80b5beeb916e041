#!/usr/bin/env bash
# The viewer in a real browser: installs Debian's chromium if missing and the test's npm
# package (playwright-core), installs `tissue` into target/browser-test/install (a copy of the
# test build's binary; `BROWSER_TEST_CARGO_INSTALL=1` runs `cargo install` instead) and starts
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
mkdir -p "$OUT/install/bin"
if [ "${BROWSER_TEST_CARGO_INSTALL:-0}" = 1 ]; then
    # The user's way. It compiles everything again: `cargo install` resolves features for
    # tissue-cli alone, not as the workspace's tests do.
    cargo install --quiet --locked --force --path crates/tissue-cli --root "$OUT/install" \
        --target-dir "$ROOT/target"
else
    # The binary the test build made (a no-op after `cargo test --release --workspace`),
    # copied out of the repository: what `cargo install` does, without compiling again.
    cargo test --quiet --release --workspace --locked --no-run
    cp "$ROOT/target/release/tissue" "$OUT/install/bin/tissue"
fi
echo "browser-test: build and install ${SECONDS} s"
SECONDS=0

mkdir -p "$OUT"
EMPTY=$(mktemp -d)
SERVERS=()
cleanup() {
    for pid in "${SERVERS[@]}"; do kill "$pid" 2>/dev/null || true; wait "$pid" 2>/dev/null || true; done
    rmdir "$EMPTY" 2>/dev/null || true
}
trap cleanup EXIT

# serve SCENE NAME: starts `tissue view SCENE` from an empty folder, logs to $OUT/NAME.log,
# sets URL to the printed address and SERVER to its pid.
serve() {
    local log="$OUT/$2.log"
    # Emptied here, not by the background start's redirection: the loop below must never
    # read an address an earlier run left in the file (the new server may not have started).
    : >"$log"
    (cd "$EMPTY" && exec env -u TISSUE_VIEWER_DIR "$OUT/install/bin/tissue" view \
        "$ROOT/scenes/$1" --port 0) >"$log" 2>&1 &
    SERVER=$!
    SERVERS+=("$SERVER")
    URL=""
    for _ in $(seq 1 3000); do
        URL=$(grep -o 'http://[0-9.]*:[0-9]*/?token=[0-9a-f]*' "$log" | head -n1 || true)
        [ -n "$URL" ] && return 0
        if ! kill -0 "$SERVER" 2>/dev/null; then cat "$log"; echo "browser-test: the server for $1 died"; exit 1; fi
        sleep 0.1
    done
    cat "$log"; echo "browser-test: no URL printed for $1"; exit 1
}

# `--matrix`: the switch matrix (every kind, a 2 s probe) on every shipped scene instead of
# the CI checks. Long (the bem builds alone take minutes): not part of CI. `MATRIX_SCENES`
# ("a.toml b.toml") runs only those scenes; `MATRIX_SWITCH_MS` is the wait for one switch.
if [ "${1:-}" = "--matrix" ]; then
    failed=0
    : >"$OUT/matrix.log"
    for path in "$ROOT"/scenes/*.toml; do
        scene=$(basename "$path")
        if [ -n "${MATRIX_SCENES:-}" ] && [[ " $MATRIX_SCENES " != *" $scene "* ]]; then continue; fi
        serve "$scene" "matrix-${scene%.toml}"
        timeout 1800 node viewer/tests/matrix.test.mjs "$URL" | tee -a "$OUT/matrix.log" || failed=$((failed + 1))
        kill "$SERVER" 2>/dev/null || true
    done
    grep '^info switch matrix' "$OUT/matrix.log"
    echo "browser-test --matrix: $failed scenes with failures"
    exit $((failed > 0))
fi

serve liver-probe.toml server
LOG="$OUT/server.log"
echo "browser-test: $URL"

status=0
timeout 240 node viewer/tests/browser.test.mjs "$URL" "$OUT/screenshot.png" | tee "$OUT/page.log" \
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
kill "$SERVER" 2>/dev/null || true

# The other scenes, one server at a time: every cutting kind's cut scene (incision,
# Reset; bem through its background incision), the voxel pelvis (frame rate).
: >"$OUT/scenes.log"
for scene in ${BROWSER_TEST_SCENES:-liver-spring-mass-cut liver-tensor-mass-cut liver-linked-volumes-cut liver-bem-cut pelvis-chainmail}; do
    serve "$scene.toml" "$scene"
    s2=0
    SHOTS="$OUT" timeout 120 node viewer/tests/scenes.test.mjs "$URL" >"$OUT/scene.log" || s2=$?
    cat "$OUT/scene.log" | tee -a "$OUT/scenes.log"
    p2=$(grep -c '^ok ' "$OUT/scene.log" || true)
    f2=$(grep -c '^FAIL' "$OUT/scene.log" || true)
    if [ "$s2" != 0 ] && [ "$f2" = 0 ]; then f2=1; echo "FAIL $scene: the page test stopped ($s2)"; fi
    passed=$((passed + p2)); failed=$((failed + f2))
    kill "$SERVER" 2>/dev/null || true
done

[ "$failed" = 0 ] || status=1
echo "browser-test: page and checks ${SECONDS} s"
echo "browser: $passed passed, $failed failed"
exit "$status"

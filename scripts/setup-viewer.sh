#!/usr/bin/env bash
# Installs the browser test's JavaScript dependencies (playwright-core) into
# viewer/node_modules from the npm registry. `tissue view` itself needs none of this: the page
# and three.js (vendored in viewer/vendor/three) are built into the binary.
set -euo pipefail
cd "$(dirname "$0")/../viewer"
if ! command -v npm >/dev/null; then
    echo "setup-viewer: npm is not installed (install Node.js and npm first)" >&2
    exit 1
fi
if [ -f package-lock.json ]; then
    npm ci --no-audit --no-fund
else
    npm install --no-audit --no-fund
fi
test -d node_modules/playwright-core
echo "setup-viewer: playwright-core installed in viewer/node_modules"

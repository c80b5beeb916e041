#!/usr/bin/env bash
# Installs the browser viewer's JavaScript dependencies (three.js) into viewer/node_modules
# from the npm registry, so that `tissue view` can serve them locally (no CDN).
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
test -f node_modules/three/build/three.module.js
echo "setup-viewer: three.js installed in viewer/node_modules"

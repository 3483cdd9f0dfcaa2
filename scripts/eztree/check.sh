#!/usr/bin/env bash
# Exports every EZ-Tree preset at its own seed and at SEEDS more (default 1 2 3), then
# checks that each imports and hangs >= 95% of its branches on their true parent
# (tests/eztree.rs). Needs node and npm (the npm registry) the first time.
#
#   scripts/eztree/check.sh [SEED ...]
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
seeds=("${@:-1 2 3}")
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
cd "$here"
[ -d node_modules ] || npm install --no-audit --no-fund >/dev/null
presets=$(node export.mjs --list)
args=()
while IFS= read -r preset; do
  args+=("$preset")
  for seed in ${seeds[@]}; do args+=("$preset:$seed"); done
done <<< "$presets"
node export.mjs "$out" "${args[@]}" 2>/dev/null | grep -v '^GLTFExporter' || true
cd "$here/../.."
SHERWOOD_EZTREE_DIR="$out" cargo test --release --test eztree -- --nocapture

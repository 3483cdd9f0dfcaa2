#!/usr/bin/env bash
# The large forest at a target Robin Hood cannot hold (issue #26): every strategy that
# keeps the frame complete or on time, side by side, on both camera paths at full length,
# with a screenshot of each at one frame; and the identical-frame noise floor of the
# hierarchical strategy at the same target, measured in the same session.
#
#   scripts/large-forest.sh
#
# Override with TREES (20000), TARGET (ms, 100), STRATEGIES (hierarchical robin-hood
# funkhouser), PATHS (linear zigzag), SHOT (the measured frame screenshotted, 600) and
# HOLD_FRAMES (400). Resumable like scripts/reproduce.sh: results/large/<name>.csv and
# .summary are written when a run completes; delete results/large to start over. Then
# `cargo run --release -p sherwood-lab -- results --large results/large docs` writes
# docs/large-forest.md.
set -euo pipefail
cd "$(dirname "$0")/.."

TREES=${TREES:-20000}
TARGET=${TARGET:-100}
STRATEGIES=${STRATEGIES:-"hierarchical robin-hood funkhouser"}
PATHS=${PATHS:-"linear zigzag"}
SHOT=${SHOT:-600}
HOLD_FRAMES=${HOLD_FRAMES:-400}
RAW=results/large
mkdir -p "$RAW" docs/large-forest
target_dir=${CARGO_TARGET_DIR:-target}

cargo build --release --bin sherwood-lab
lab="$target_dir/release/sherwood-lab"
forest=("$lab" forest)
source "$(dirname "$0")/lib/runs.sh"

ecosystem="forests/trees-$TREES.ecosystem.ron"
printf 'forest: %s\ntarget: %s ms\nstrategies: %s\npaths: %s\nnoise floor: %s identical frames at frame %s of the first path\n' \
    "$ecosystem" "$TARGET" "$STRATEGIES" "$PATHS" "$HOLD_FRAMES" "$SHOT" > "$RAW/GRID"

first_path=${PATHS%% *}
run "${TREES}_${first_path}_hold_hierarchical" --ecosystem "$ecosystem" --path "$first_path" \
    --hold-frame "$SHOT" --frames "$HOLD_FRAMES" --target-ms "$TARGET" --strategy hierarchical
for path in $PATHS; do
    for strategy in $STRATEGIES; do
        run "${TREES}_${path}_${strategy}" --ecosystem "$ecosystem" --path "$path" \
            --target-ms "$TARGET" --strategy "$strategy" --no-hud \
            --screenshot "docs/large-forest/${TREES}-${path}-${strategy}.png" --at-frame "$SHOT"
    done
done

#!/usr/bin/env bash
# The soak: a long headless run (`sherwood-lab soak`, lab/src/soak.rs: a 100-tree forest at a 10 ms target, a
# moving camera, wind, trees spawned and despawned every 100 frames, the strategy changed
# every 5 000 frames), reporting resident memory and the learned costs every 1 000 frames
# and every error or warning logged.
#
#   scripts/soak.sh                  # 100 000 frames, ~20–30 minutes on lavapipe
#
# Override FRAMES, TREES, TARGET_MS, CARGO_FLAGS and OUT (results/soak).
set -euo pipefail
cd "$(dirname "$0")/.."

FRAMES=${FRAMES:-100000}
TREES=${TREES:-100}
TARGET_MS=${TARGET_MS:-10}
OUT=${OUT:-results/soak}
mkdir -p "$OUT"
target_dir=${CARGO_TARGET_DIR:-target}

# shellcheck disable=SC2086
cargo build --release ${CARGO_FLAGS:-} --bin sherwood-lab
"$target_dir/release/sherwood-lab" soak --frames "$FRAMES" --trees "$TREES" --target-ms "$TARGET_MS" \
    > "$OUT/soak.txt" 2> "$OUT/soak.log"
grep '^soak ' "$OUT/soak.txt" | awk '
    { for (i = 2; i <= NF; i++) { split($i, kv, "="); v[kv[1]] = kv[2] } }
    v["frame"] == 10000 { rss0 = v["rss_mb"] }
    { rss = v["rss_mb"] }
    END { if (rss0 > 0) printf "rss at frame 10000: %.1f MiB, at the end: %.1f MiB (%+.2f%%)\n", rss0, rss, 100 * (rss / rss0 - 1) }'
echo "errors logged: $(grep -c 'ERROR' "$OUT/soak.log" || true), warnings: $(grep -c 'WARN' "$OUT/soak.log" || true)"

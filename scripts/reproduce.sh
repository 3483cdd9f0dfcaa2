#!/usr/bin/env bash
# Reproduces the paper's frame-time tables on this machine: for each forest size and
# camera path, an unlimited run, then TC and TCLOD runs at targets spread over 1/16 to
# 1/2 of the unlimited peak, plus TCLOD without online correction at the middle target;
# then docs/results.md and the plots (examples/results.rs).
#
#   scripts/reproduce.sh             # the full grid (hours on a 2-core software renderer)
#   scripts/reproduce.sh --reduced   # 600 and 2000 trees, paths squeezed to 200 frames
#
# Resumable: each run writes results/raw/<name>.csv only when it completes, and runs
# whose file exists are skipped; delete results/raw to start over. Override the grid
# with SIZES, PATHS, FRACTIONS and PATH_FRAMES (empty: the paper's path lengths).
set -euo pipefail
cd "$(dirname "$0")/.."

SIZES=${SIZES:-"600 1000 2000"}
PATHS=${PATHS:-"linear zigzag"}
FRACTIONS=${FRACTIONS:-"0.0625 0.125 0.25 0.375 0.5"}
PATH_FRAMES=${PATH_FRAMES:-}
if [[ "${1:-}" == "--reduced" ]]; then
    SIZES=${SIZES_REDUCED:-"600 2000"}
    PATH_FRAMES=${PATH_FRAMES:-200}
elif [[ -n "${1:-}" ]]; then
    echo "usage: scripts/reproduce.sh [--reduced]" >&2
    exit 2
fi
RAW=results/raw
mkdir -p "$RAW"
target_dir=${CARGO_TARGET_DIR:-target}

cargo build --release --example forest --example results
forest="$target_dir/release/examples/forest"

frames_flag=()
if [[ -n "$PATH_FRAMES" ]]; then
    frames_flag=(--path-frames "$PATH_FRAMES")
fi
paper_lengths="the paper lengths (linear 1100, zigzag 1700)"
printf 'sizes: %s\npaths: %s\nfractions of the unlimited peak: %s\npath frames: %s\n' \
    "$SIZES" "$PATHS" "$FRACTIONS" "${PATH_FRAMES:-$paper_lengths}" > "$RAW/GRID"

source "$(dirname "$0")/lib/runs.sh"

for size in $SIZES; do
    for path in $PATHS; do
        common=(--trees "$size" --path "$path" "${frames_flag[@]}")
        run "$size-$path-unlimited" "${common[@]}" --mode unlimited
        peak=$(awk -F, 'NR > 1 && $6 > max { max = $6 } END { printf "%.1f", max }' "$RAW/$size-$path-unlimited.csv")
        for fraction in $FRACTIONS; do
            target=$(awk -v p="$peak" -v f="$fraction" 'BEGIN { printf "%.1f", p * f }')
            for mode in tc tclod; do
                run "$size-$path-$mode-$fraction" "${common[@]}" --mode "$mode" --target-ms "$target"
            done
        done
        middle=$(echo "$FRACTIONS" | awk '{ print $(int((NF + 1) / 2)) }')
        target=$(awk -v p="$peak" -v f="$middle" 'BEGIN { printf "%.1f", p * f }')
        run "$size-$path-tclod-$middle-nocorr" "${common[@]}" --mode tclod --target-ms "$target" --no-correction
    done
done

"$target_dir/release/examples/results" "$RAW" docs

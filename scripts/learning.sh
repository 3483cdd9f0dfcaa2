#!/usr/bin/env bash
# The cost model's grid: how well the budget predicts and holds its target on this
# machine, with the shipped calibration and with one that is 3× too dear or too cheap.
# For the default forest (or SIZE trees): the identical-frame noise floor (the camera held
# at the linear path's busiest frame, full detail and the static LOD), both paths at
# their full length (linear 1100, zigzag 1700 frames) unlimited, then TC and TCLOD at
# FRACTIONS of the unlimited peak with each calibration scale in SCALES, and at 3/4 of
# the peak with the shipped calibration; then docs/cost-model.md (`sherwood-lab cost-report`, lab/src/cost_report.rs).
#
#   scripts/learning.sh             # about an hour and a half on a 2-core software renderer
#
# Resumable: each run writes results/learning/<name>.csv only when it completes, and runs
# whose file exists are skipped; delete results/learning to start over. Nothing else may
# run on the machine meanwhile: the runs are timings.
set -euo pipefail
cd "$(dirname "$0")/.."

SIZE=${SIZE:-600}
PATHS=${PATHS:-"linear zigzag"}
FRACTIONS=${FRACTIONS:-"0.25 0.5"}
SCALES=${SCALES:-"1 3 0.333"}
HOLD_FRAMES=${HOLD_FRAMES:-300}
RAW=${RAW:-results/learning}
mkdir -p "$RAW"
target_dir=${CARGO_TARGET_DIR:-target}

cargo build --release --bin sherwood-lab
lab="$target_dir/release/sherwood-lab"
forest=("$lab" forest)

source "$(dirname "$0")/lib/runs.sh"
# Frame 0 is the first frame drawn: the learning is recorded from its start.
common=(--trees "$SIZE" --warmup 0 --no-wind)

# The frame (path index) of a run's largest measured frame time.
busiest() {
    awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "measured_ms") c = i; next }
             $c > max { max = $c; frame = $1 } END { print frame }' "$1"
}

# The peak frame time of a run.
peak() {
    awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "measured_ms") c = i; next }
             $c > max { max = $c } END { printf "%.1f", max }' "$1"
}

for path in $PATHS; do
    run "$SIZE-$path-unlimited" "${common[@]}" --path "$path" --mode unlimited
done
hold=$(busiest "$RAW/$SIZE-linear-unlimited.csv")
for mode in unlimited static; do
    run "$SIZE-linear-$mode-hold$hold" "${common[@]}" --path linear --hold-frame "$hold" \
        --frames "$HOLD_FRAMES" --mode "$mode"
done
for path in $PATHS; do
    top=$(peak "$RAW/$SIZE-$path-unlimited.csv")
    for mode in tc tclod; do
        for fraction in $FRACTIONS; do
            target=$(awk -v p="$top" -v f="$fraction" 'BEGIN { printf "%.1f", p * f }')
            for scale in $SCALES; do
                run "$SIZE-$path-$mode-$fraction-x$scale" "${common[@]}" --path "$path" \
                    --mode "$mode" --target-ms "$target" --scale-calibration "$scale"
            done
        done
        target=$(awk -v p="$top" 'BEGIN { printf "%.1f", p * 0.75 }')
        run "$SIZE-$path-$mode-0.75-x1" "${common[@]}" --path "$path" --mode "$mode" \
            --target-ms "$target"
    done
done

"$lab" cost-report "$RAW" docs

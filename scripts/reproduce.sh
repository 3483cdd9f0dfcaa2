#!/usr/bin/env bash
# Reproduces the paper's frame-time tables on this machine, every strategy side by side:
# for each forest size and target, the identical-frame noise floor (the camera held at
# the unlimited peak's frame of the first path); for each size and camera path at full length, an
# unlimited run, then each mode (TC, TCLOD) with each strategy at targets of 1/16 to 1/2
# of the unlimited peak, plus TCLOD Robin Hood without online correction at the middle
# target; every timed run scores its hand-out against the LP bound (--benefit). Then
# docs/results.md and the plots (`sherwood-lab results`, lab/src/results.rs).
#
#   scripts/reproduce.sh             # the full grid (a day on a 2-core software renderer)
#   scripts/reproduce.sh --reduced   # 600 trees, one path, 1/8 1/4 1/2, paths of 300 frames
#
# Resumable: each run writes results/raw/<name>.csv only when it completes, and runs
# whose file exists are skipped; delete results/raw to start over (a grid measured across
# sessions mixes machines: its times are not comparable). Override the grid with SIZES,
# PATHS, FRACTIONS, MODES, STRATEGIES, HOLD_FRAMES and PATH_FRAMES (empty: the paper's
# path lengths).
set -euo pipefail
cd "$(dirname "$0")/.."

SIZES=${SIZES:-"600 1000 2000"}
PATHS=${PATHS:-"linear zigzag"}
FRACTIONS=${FRACTIONS:-"0.0625 0.125 0.25 0.5"}
MODES=${MODES:-"tc tclod"}
STRATEGIES=${STRATEGIES:-"robin-hood funkhouser funkhouser-incremental triangle-budget"}
HOLD_FRAMES=${HOLD_FRAMES:-400}
PATH_FRAMES=${PATH_FRAMES:-}
if [[ "${1:-}" == "--reduced" ]]; then
    SIZES=${SIZES_REDUCED:-600}
    PATHS=${PATHS_REDUCED:-zigzag}
    FRACTIONS=${FRACTIONS_REDUCED:-"0.125 0.25 0.5"}
    PATH_FRAMES=${PATH_FRAMES:-300}
    HOLD_FRAMES=${HOLD_FRAMES_REDUCED:-200}
elif [[ -n "${1:-}" ]]; then
    echo "usage: scripts/reproduce.sh [--reduced]" >&2
    exit 2
fi
RAW=results/raw
mkdir -p "$RAW"
target_dir=${CARGO_TARGET_DIR:-target}

cargo build --release --bin sherwood-lab
lab="$target_dir/release/sherwood-lab"
forest=("$lab" forest)

frames_flag=()
if [[ -n "$PATH_FRAMES" ]]; then
    frames_flag=(--path-frames "$PATH_FRAMES")
fi
paper_lengths="the paper lengths (linear 1100, zigzag 1700)"
printf 'sizes: %s\npaths: %s\nfractions of the unlimited peak: %s\nmodes: %s\nstrategies: %s\npath frames: %s\nnoise floor: %s identical frames\n' \
    "$SIZES" "$PATHS" "$FRACTIONS" "$MODES" "$STRATEGIES" "${PATH_FRAMES:-$paper_lengths}" "$HOLD_FRAMES" > "$RAW/GRID"

source "$(dirname "$0")/lib/runs.sh"

middle=$(echo "$FRACTIONS" | awk '{ print $(int((NF + 1) / 2)) }')

for size in $SIZES; do
    first_path=""
    for path in $PATHS; do
        # The paper's tables hold the mean at the target (the library's default goal
        # holds a tail instead: see FrameGoal).
        common=(--trees "$size" --path "$path" --goal mean "${frames_flag[@]}")
        run "${size}_${path}_unlimited" "${common[@]}" --mode unlimited
        read -r peak peak_frame < <(peak_of "${size}_${path}_unlimited")
        if [[ -z "$first_path" ]]; then
            first_path=$path
            for fraction in $FRACTIONS; do
                run "${size}_${path}_hold_${fraction}" "${common[@]}" --mode tclod \
                    --target-ms "$(fraction_of "$peak" "$fraction")" --hold-frame "$peak_frame" \
                    --frames "$HOLD_FRAMES" --benefit
            done
        fi
        for fraction in $FRACTIONS; do
            target=$(fraction_of "$peak" "$fraction")
            for mode in $MODES; do
                for strategy in $STRATEGIES; do
                    run "${size}_${path}_${mode}_${strategy}_${fraction}" "${common[@]}" \
                        --mode "$mode" --strategy "$strategy" --target-ms "$target" --benefit
                done
            done
        done
        run "${size}_${path}_tclod_robin-hood_${middle}_nocorr" "${common[@]}" --mode tclod \
            --target-ms "$(fraction_of "$peak" "$middle")" --no-correction --benefit
    done
done

"$lab" results "$RAW" docs

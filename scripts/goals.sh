#!/usr/bin/env bash
# The frame-time promise side by side: the tail goal (the default FrameBudget: at most 5%
# of frames over 1.1 x target, aimed by the learned scatter) against the paper's mean goal
# and fixed-headroom baselines (the mean goal aimed at 0.85, 0.9 - Unreal's choice - and
# 0.95 x target), TCLOD Robin Hood, on both camera paths at full length. Per forest, the
# noise floor first: identical frames at the unlimited peak's frame with the tail goal, at
# each target. Then docs/goals.md (`sherwood-lab goals`, lab/src/goals.rs).
#
#   scripts/goals.sh        # 600 trees, linear and zigzag, 1/8 1/4 1/2 of the peak
#
# Resumable like scripts/reproduce.sh (each run's file written when it completes; delete
# results/goals to start over). Override with SIZES, PATHS, FRACTIONS, GOALS (tail, mean,
# cut = the tail goal cutting its aim after 2 frames over, hF = the mean goal at F x
# target), HOLD_FRAMES and PATH_FRAMES (empty: the paper's lengths, linear 1100 and zigzag
# 1700 frames).
set -euo pipefail
cd "$(dirname "$0")/.."

SIZES=${SIZES:-600}
PATHS=${PATHS:-"linear zigzag"}
FRACTIONS=${FRACTIONS:-"0.125 0.25 0.5"}
GOALS=${GOALS:-"tail mean h0.85 h0.90 h0.95"}
HOLD_FRAMES=${HOLD_FRAMES:-300}
PATH_FRAMES=${PATH_FRAMES:-}
RAW=${RAW:-results/goals}
DOCS=${DOCS:-docs}
mkdir -p "$RAW"
target_dir=${CARGO_TARGET_DIR:-target}

cargo build --release --bin sherwood-lab
lab="$target_dir/release/sherwood-lab"
forest=("$lab" forest)
frames_flag=()
if [[ -n "$PATH_FRAMES" ]]; then
    frames_flag=(--path-frames "$PATH_FRAMES")
fi
printf 'sizes: %s\npaths: %s\nfractions of the unlimited peak: %s\ngoals: %s\npath frames: %s\nnoise floor: %s identical frames\n' \
    "$SIZES" "$PATHS" "$FRACTIONS" "$GOALS" "${PATH_FRAMES:-the paper lengths}" "$HOLD_FRAMES" > "$RAW/GRID"

source "$(dirname "$0")/lib/runs.sh"

goal_flags() {
    case "$1" in
        tail) echo "--goal tail" ;;
        cut) echo "--goal tail --overrun-cut 2" ;;
        mean) echo "--goal mean" ;;
        h*) echo "--goal mean --headroom ${1#h}" ;;
        *) echo "unknown goal $1" >&2; exit 2 ;;
    esac
}

for size in $SIZES; do
    first_path=""
    for path in $PATHS; do
        common=(--trees "$size" --path "$path" --mode tclod --strategy robin-hood "${frames_flag[@]}")
        run "${size}_${path}_unlimited" --trees "$size" --path "$path" --mode unlimited "${frames_flag[@]}"
        read -r peak peak_frame < <(peak_of "${size}_${path}_unlimited")
        if [[ -z "$first_path" ]]; then
            first_path=$path
            for fraction in $FRACTIONS; do
                target=$(fraction_of "$peak" "$fraction")
                run "${size}_${path}_hold_${fraction}" "${common[@]}" --goal tail \
                    --target-ms "$target" --hold-frame "$peak_frame" --frames "$HOLD_FRAMES"
            done
        fi
        for fraction in $FRACTIONS; do
            target=$(fraction_of "$peak" "$fraction")
            for goal in $GOALS; do
                # shellcheck disable=SC2046
                run "${size}_${path}_${goal}_${fraction}" "${common[@]}" --target-ms "$target" \
                    $(goal_flags "$goal")
            done
        done
    done
done

"$lab" goals "$RAW" "$DOCS"

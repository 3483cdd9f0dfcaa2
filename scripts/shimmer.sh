#!/usr/bin/env bash
# Shimmer at a still camera: the camera held at a frame of a path, each configuration at
# fractions of a target, 16 consecutive frames after 60 of settling; per run the share of
# pixels that changed from one frame to the next (mean and largest) and ꟻLIP between
# them (`sherwood-lab quality shimmer`), and the measured mean frame time. Full detail
# is deterministic (0%); the goal is at most 0.1% a frame.
#
#   scripts/shimmer.sh
#
# Override with TREES (default: the ecosystem's), PATH_NAME, HOLD (the path's frame), TARGETS (ms), CONFIGS
# (`name:flags`, flags comma-separated), RUNS, OUT and LAB (a built sherwood-lab to run
# instead of building this tree's, to compare builds). Prints a Markdown table.
set -euo pipefail
cd "$(dirname "$0")/.."

TREES=${TREES:-}
PATH_NAME=${PATH_NAME:-linear}
HOLD=${HOLD:-500}
TARGETS=${TARGETS:-"30 60 120"}
CONFIGS=${CONFIGS:-"tclod-gradual: tclod-sudden:--sudden tclod-every-frame:--no-steady tc-gradual:--mode,tc tc-every-frame:--mode,tc,--no-steady"}
RUNS=${RUNS:-3}
OUT=${OUT:-results/shimmer}
mkdir -p "$OUT"
target_dir=${CARGO_TARGET_DIR:-target}
lab=${LAB:-}
if [[ -z "$lab" ]]; then
    cargo build --release --bin sherwood-lab
    lab="$target_dir/release/sherwood-lab"
fi
frames=$(seq -s, 60 75)
trees=()
[[ -n "$TREES" ]] && trees=(--trees "$TREES")

echo "| trees | path@frame | target ms | config | run | time ms | changed mean | changed max | ꟻLIP mean | ꟻLIP max | kept |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
for target in $TARGETS; do
    for config in $CONFIGS; do
        name=${config%%:*}
        IFS=, read -r -a flags <<< "${config#*:}"
        for run in $(seq 1 "$RUNS"); do
            base="$OUT/${TREES:-default}-$PATH_NAME-$HOLD-$target-$name-$run"
            "$lab" forest --headless --no-wind --no-hud "${trees[@]}" --path "$PATH_NAME" \
                --hold-frame "$HOLD" --target-ms "$target" --warmup 10 --frames 80 \
                --at-frame "$frames" --screenshot "$base.png" --record "$base.csv" \
                "${flags[@]}" > /dev/null 2>&1
            shots=()
            for k in $(seq 60 75); do shots+=("$base-$k.png"); done
            declare -A q=()
            for pair in $("$lab" quality shimmer "${shots[@]}"); do q[${pair%%=*}]=${pair#*=}; done
            stats=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) c[$i] = i; next }
                NR > 11 { t += $c["measured_ms"]; k += $c["selection_kept"]; n++ }
                END { printf "%.1f %d/%d", t / n, k, n }' "$base.csv")
            read -r time kept <<< "$stats"
            printf '| %s | %s@%s | %s | %s | %s | %s | %.4f%% | %.4f%% | %s | %s | %s |\n' \
                "${TREES:-default}" "$PATH_NAME" "$HOLD" "$target" "$name" "$run" "$time" \
                "$(awk -v x="${q[changed_mean]}" 'BEGIN { print 100 * x }')" \
                "$(awk -v x="${q[changed_max]}" 'BEGIN { print 100 * x }')" \
                "${q[flip_mean]}" "${q[flip_max]}" "$kept"
            rm -f "${shots[@]}"
            unset q
        done
    done
done

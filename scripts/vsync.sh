#!/usr/bin/env bash
# The frame-time promise with vsync on and off, in an app as a user writes it
# (`sherwood-lab user-app`, lab/src/user_app.rs: DefaultPlugins, Bevy's default present mode, the default forest,
# a still camera) and along the forest tool's paths. Runs under Xvfb, which has no
# vertical blank: EmulatedVsyncPlugin supplies one (--vsync-hz).
#
#   scripts/vsync.sh                 # HZ=20: targets 0.9 and 1.0 periods, 3 rounds
#
# Each round runs every configuration once, vsync off and on alternated, so that the
# machine's slow regimes fall on both; the noise floor (static LOD: identical frames, no
# vsync) is measured in every round. Results: results/vsync/*.txt, one line per run.
# Override HZ, ROUNDS, FRAMES, TARGETS (in periods), EXTRA (more user_app flags, e.g.
# "--msaa 1"), FOREST_FRACTIONS (the forest
# tool's targets as fractions of PEAK_MS, its unlimited peak on the zigzag path;
# empty: skip the forest tool) and FOREST_FLAGS (more forest flags, e.g.
# "--path-frames 300").
set -euo pipefail
cd "$(dirname "$0")/.."

HZ=${HZ:-20}
ROUNDS=${ROUNDS:-3}
FRAMES=${FRAMES:-300}
TARGETS=${TARGETS:-"0.9 1.0"}
FOREST_FRACTIONS=${FOREST_FRACTIONS:-}
PEAK_MS=${PEAK_MS:-}
FOREST_FLAGS=${FOREST_FLAGS:-}
EXTRA=${EXTRA:-}
OUT=${OUT:-results/vsync}
mkdir -p "$OUT"
target_dir=${CARGO_TARGET_DIR:-target}

# CARGO_FLAGS: the build's flags (e.g. --all-features, to reuse a build made so).
# shellcheck disable=SC2086
cargo build --release ${CARGO_FLAGS:-} --bin sherwood-lab
lab="$target_dir/release/sherwood-lab"
user_app=("$lab" user-app)
forest=("$lab" forest)
period_ms=$(awk -v hz="$HZ" 'BEGIN { printf "%.3f", 1000 / hz }')

# The binaries find assets/ through BEVY_ASSET_ROOT (cargo sets CARGO_MANIFEST_DIR).
export BEVY_ASSET_ROOT=$PWD
windowed() {
    xvfb-run -a -s "-screen 0 1280x720x24" "$@"
}

for round in $(seq 1 "$ROUNDS"); do
    echo "== round $round"
    # shellcheck disable=SC2086
    windowed "${user_app[@]}" $EXTRA --mode static --target-ms "$period_ms" --frames "$FRAMES" \
        | tee -a "$OUT/noise.txt"
    for t in $TARGETS; do
        target=$(awk -v p="$period_ms" -v t="$t" 'BEGIN { printf "%.2f", p * t }')
        # shellcheck disable=SC2086
        windowed "${user_app[@]}" $EXTRA --target-ms "$target" --frames "$FRAMES" | tee -a "$OUT/user_app_$t.txt"
        # shellcheck disable=SC2086
        windowed "${user_app[@]}" $EXTRA --target-ms "$target" --frames "$FRAMES" --vsync-hz "$HZ" \
            | tee -a "$OUT/user_app_$t.txt"
    done
    if [[ -n "$FOREST_FRACTIONS" ]]; then
        for f in $FOREST_FRACTIONS; do
            target=$(awk -v p="$PEAK_MS" -v f="$f" 'BEGIN { printf "%.1f", p * f }')
            hz=$(awk -v t="$target" 'BEGIN { printf "%.3f", 1000 / t }')
            for vsync in "" "--vsync-hz $hz"; do
                # shellcheck disable=SC2086
                windowed "${forest[@]}" --no-hud --no-wind --path zigzag --summary $FOREST_FLAGS \
                    --target-ms "$target" $vsync \
                    | sed "s/^summary/forest_$f vsync=${vsync:+$hz}/" | tee -a "$OUT/forest_$f.txt"
            done
        done
    fi
done

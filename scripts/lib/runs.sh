# Shared by the measurement scripts: `run NAME FLAGS...` runs the lab's forest tool
# (the command in the array "forest") headless with FLAGS, recording into "$RAW/NAME.csv" and its summary line into
# "$RAW/NAME.summary" only once it completes; a run whose file exists is skipped, so the
# scripts can be stopped and resumed. A run that fails is reported (and listed in
# "$RAW/FAILED") and the script goes on; it is tried again when the script is run again.
run() {
    local name=$1
    shift
    if [[ -f "$RAW/$name.csv" ]]; then
        return
    fi
    echo "== $name: $*"
    local status=0
    "${forest[@]}" --headless --summary --record "$RAW/$name.csv.part" "$@" > "$RAW/$name.summary.part" || status=$?
    if [[ $status -ne 0 ]]; then
        echo "== $name FAILED (exit $status)" | tee -a "$RAW/FAILED"
        rm -f "$RAW/$name.csv.part" "$RAW/$name.summary.part"
        return
    fi
    cat "$RAW/$name.summary.part"
    mv "$RAW/$name.summary.part" "$RAW/$name.summary"
    mv "$RAW/$name.csv.part" "$RAW/$name.csv"
}

# The peak frame time of the run "$RAW/NAME.csv" and the measured frame it fell on.
peak_of() {
    awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "measured_ms") c = i; next }
             $c > max { max = $c; at = $1 } END { printf "%.1f %d\n", max, at }' "$RAW/$1.csv"
}

# PEAK × FRACTION, to a tenth of a millisecond: a target as the runs' names give it.
fraction_of() {
    awk -v p="$1" -v f="$2" 'BEGIN { printf "%.1f", p * f }'
}

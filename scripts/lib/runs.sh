# Shared by the measurement scripts: `run NAME FLAGS...` runs the forest example
# ("$forest") headless with FLAGS, recording into "$RAW/NAME.csv" and its summary line into
# "$RAW/NAME.summary" only once it completes; a run whose file exists is skipped, so the
# scripts can be stopped and resumed.
run() {
    local name=$1
    shift
    if [[ -f "$RAW/$name.csv" ]]; then
        return
    fi
    echo "== $name: $*"
    "$forest" --headless --summary --record "$RAW/$name.csv.part" "$@" > "$RAW/$name.summary.part"
    cat "$RAW/$name.summary.part"
    mv "$RAW/$name.summary.part" "$RAW/$name.summary"
    mv "$RAW/$name.csv.part" "$RAW/$name.csv"
}

#!/usr/bin/env bash
# Runs the same host-sim command lines with two binaries (e.g. before and
# after a refactor) and compares everything they produce byte for byte:
# stdout, stderr, the exit code and every file written (JSON, CSV, TOML,
# PNG, HTML). Covers every subcommand's --help, run with all its outputs,
# summary, observability, montecarlo, record + calibrate (frames with a
# report, CSV with a platform file, a damaged stream), checks, design, paper
# and the one-line errors of bad arguments. Lines that report wall time
# (progress lines, `wall_s`, the summary's wall column) are dropped first.
# Prints one line per case and exits 1 if any case differs.
# Usage: tools/compare-cli.sh OLD_HOST_SIM NEW_HOST_SIM [OUT_DIR]
set -uo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
OLD=$(realpath "$1") NEW=$(realpath "$2") OUT=${3:-$(mktemp -d)}
mkdir -p "$OUT"
OUT=$(realpath "$OUT")
SC="$ROOT/scenarios"
DIFFER=0

# case NAME ARGS...: runs `BIN ARGS...` in OUT/{old,new}/NAME/ (ARGS may name
# files relative to it; @IN@ stands for OUT/inputs).
case_() {
    local name=$1
    shift
    for side in old new; do
        local bin=$OLD dir="$OUT/$side/$name"
        [ "$side" = new ] && bin=$NEW
        rm -rf "$dir"
        mkdir -p "$dir"
        local args=()
        for a in "$@"; do args+=("${a//@IN@/$OUT/inputs}"); done
        (cd "$dir" && "$bin" "${args[@]}" >stdout 2>stderr </dev/null; echo $? >rc)
        # Wall-time figures are not answers: progress lines (their order
        # follows the threads), `wall_s` in JSON, the summary's wall column.
        sed -i -E '/^[a-z]+: ([a-z0-9 -]+: )?[0-9]+\/[0-9]+ /d; /wall time|done in [0-9.]+ ?s|[0-9.]+ s wall/d; s/ +[0-9]+\.[0-9]+$//; s/, [0-9.]+ s: [0-9]+ candidates\/min/, T/; s/took [0-9.]+ s \(in parallel\), everything [0-9.]+ s/took T/' "$dir/stdout" "$dir/stderr"
        find "$dir" -name '*.json' -exec sed -i -E 's/"wall_s": [-0-9.e]+/"wall_s": T/' {} +
        # Paths of the two sides differ only by old/new.
        sed -i "s#$OUT/$side#OUT#g" "$dir/stdout" "$dir/stderr"
    done
    if diff -r "$OUT/old/$name" "$OUT/new/$name" >"$OUT/$name.diff" 2>&1; then
        printf '%-34s identical (rc %s, %s files)\n' "$name" "$(cat "$OUT/old/$name/rc")" "$(find "$OUT/old/$name" -type f | wc -l)"
        rm -f "$OUT/$name.diff"
    else
        printf '%-34s DIFFER (see %s)\n' "$name" "$OUT/$name.diff"
        DIFFER=1
    fi
}

# Inputs made once by the old binary, so both sides read the same bytes.
mkdir -p "$OUT/inputs"
(
    cd "$OUT/inputs"
    "$OLD" record --config M2-ps --seed 3 --out run.bin --truth truth.json >/dev/null 2>&1
    "$OLD" record --config M2-ps --seed 2 --format csv --out run.csv --truth truth-csv.json >/dev/null 2>&1
    "$OLD" record --config M2-ps --seed 4 --drop-burst 1000:200 --bit-flips 1e-5 --accel-bias-ug 10,10,10 --out bad.bin --truth bad.json >/dev/null 2>&1
)

case_ help --help
for sub in run summary remedies observability montecarlo design record calibrate checks paper; do
    case_ "help-$sub" "$sub" --help
done
case_ run-m2ps run --config M2-ps --json r.json --csv r.csv --matrices m.json --matrices-txt m.txt --report rep
case_ run-m1pa-f32 run --config M1-pa --precision f32 --seed 5 --json r.json
case_ run-m4ps-noearth run --config M4-ps --no-earth-rate --scenario "$SC/southern-slow.toml" --json r.json
case_ summary summary
case_ observability observability --json o.json
case_ observability-noearth observability --no-earth-rate --scenario "$SC/reordered-fast.toml"
case_ montecarlo montecarlo --config M1-pa --runs 4 --json mc.json
case_ record-frames record --config M3-pa --seed 7 --out s.bin --truth t.json
case_ record-csv record --config M4-pa --seed 7 --format csv --out s.csv --truth t.json
case_ calibrate-frames calibrate --input @IN@/run.bin --truth @IN@/truth.json --json c.json --matrices m.json --report rep
case_ calibrate-pass1 calibrate --input @IN@/run.bin --passes 1 --json c.json
case_ calibrate-csv calibrate --input @IN@/run.csv --format csv --platform "$SC/platform-example.toml" --truth @IN@/truth-csv.json --json c.json
case_ calibrate-damaged calibrate --input @IN@/bad.bin --truth @IN@/bad.json --json c.json
case_ checks checks --config M1-pa --seeds 3 --json k.json
case_ design design --config m1-pa --budget-s 600 --max-rotations 1 --refine-starts 1 --axes north,east --out d.toml --figure d.png --json d.json --csv d.csv --explain
case_ paper paper --out p
case_ err-config run --config M9-xx
case_ err-scenario run --config M2-ps --scenario /nonexistent.toml
case_ err-input calibrate --input /nonexistent.bin
case_ err-design design --config M2-ps --axes sideways
case_ err-record record --config M2-ps --drop-burst nope --out x.bin

exit $DIFFER

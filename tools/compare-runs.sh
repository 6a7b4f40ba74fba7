#!/usr/bin/env bash
# Compares two host-sim binaries (e.g. before and after a change to the
# filter) on all seven configurations and the three shipped scenarios
# (seed 1, `run --json`), and on the full model (`--errors full`, the
# instrumented scenario; every configuration in f64, M1-pa and M2-ps in
# f32 too): prints per case the largest estimate difference
# in units of the first binary's σ, the largest relative σ difference and
# whether the two JSON files are byte-identical (`identical` or `DIFFER`);
# exits 1 when any pair differs in a byte (a refactor must change nothing).
# Usage: tools/compare-runs.sh OLD_HOST_SIM NEW_HOST_SIM [OUT_DIR]
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
OLD=$1 NEW=$2 OUT=${3:-$(mktemp -d)}
mkdir -p "$OUT"
for sc in paper reordered-fast southern-slow; do
    for c in M1-pa M1-ps M2-ps M3-pa M3-ps M4-pa M4-ps; do
        "$OLD" run --config "$c" --scenario "$ROOT/scenarios/$sc.toml" --json "$OUT/old-$c-$sc.json" >/dev/null 2>&1
        "$NEW" run --config "$c" --scenario "$ROOT/scenarios/$sc.toml" --json "$OUT/new-$c-$sc.json" >/dev/null 2>&1
    done
done
full=(--errors full --scenario "$ROOT/scenarios/instrumented.toml")
for c in M1-pa M1-ps M2-ps M3-pa M3-ps M4-pa M4-ps; do
    "$OLD" run --config "$c" "${full[@]}" --json "$OUT/old-$c-full.json" >/dev/null 2>&1
    "$NEW" run --config "$c" "${full[@]}" --json "$OUT/new-$c-full.json" >/dev/null 2>&1
done
for c in M1-pa M2-ps; do
    "$OLD" run --config "$c" "${full[@]}" --precision f32 --json "$OUT/old-$c-full-f32.json" >/dev/null 2>&1
    "$NEW" run --config "$c" "${full[@]}" --precision f32 --json "$OUT/new-$c-full-f32.json" >/dev/null 2>&1
done
python3 - "$OUT" <<'PY'
import glob, json, sys
out = sys.argv[1]
differ = False
for old in sorted(glob.glob(out + "/old-*.json")):
    # The installation states (rad), and the full model's instrument
    # terms (their printed units): every estimate against its σ.
    def states(path):
        j = json.load(open(path))
        return j["states"] + [
            {"estimate_rad": s["estimate"], "sigma_rad": s["sigma"]} for s in j.get("instruments", [])
        ]
    a = states(old)
    b = states(old.replace("/old-", "/new-"))
    # A term with σ = 0 is not estimated: its difference counts as 0 when
    # there is none, else as infinite.
    def rel(d, s):
        return abs(d) / s if s else (0.0 if d == 0 else float("inf"))
    dx = max(rel(x["estimate_rad"] - y["estimate_rad"], x["sigma_rad"]) for x, y in zip(a, b))
    ds = max(rel(y["sigma_rad"] - x["sigma_rad"], x["sigma_rad"]) for x, y in zip(a, b))
    same = open(old, "rb").read() == open(old.replace("/old-", "/new-"), "rb").read()
    differ = differ or not same
    print(f"{old.split('old-')[1][:-5]:<24} max |dx|/sigma {dx:.2e}   max |sigma ratio - 1| {ds:.2e}   {'identical' if same else 'DIFFER'}")
sys.exit(1 if differ else 0)
PY

#!/usr/bin/env bash
# Compares two host-sim binaries (e.g. before and after a change to the
# filter) on all seven configurations and the three shipped scenarios
# (seed 1, `run --json`): prints per case the largest estimate difference
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
python3 - "$OUT" <<'PY'
import glob, json, sys
out = sys.argv[1]
differ = False
for old in sorted(glob.glob(out + "/old-*.json")):
    a = json.load(open(old))["states"]
    b = json.load(open(old.replace("/old-", "/new-")))["states"]
    dx = max(abs(x["estimate_rad"] - y["estimate_rad"]) / x["sigma_rad"] for x, y in zip(a, b))
    ds = max(abs(y["sigma_rad"] / x["sigma_rad"] - 1) for x, y in zip(a, b))
    same = open(old, "rb").read() == open(old.replace("/old-", "/new-"), "rb").read()
    differ = differ or not same
    print(f"{old.split('old-')[1][:-5]:<24} max |dx|/sigma {dx:.2e}   max |sigma ratio - 1| {ds:.2e}   {'identical' if same else 'DIFFER'}")
sys.exit(1 if differ else 0)
PY

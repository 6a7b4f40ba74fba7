#!/usr/bin/env bash
# x86-64 instructions per period on the host, by callgrind: the filter's
# linearised period (M2-ps, M1-pa) and the dense reference of the same size
# (the criterion group `period`'s cases), each counted over 1000 and 3000
# periods and differenced (the set-up cancels). Deterministic: the counts do
# not depend on the machine's speed. Needs valgrind.
#
#   tools/host-instructions.sh
set -euo pipefail
cd "$(dirname "$0")/.."
# The bench profile (thin LTO, one codegen unit): the profile of
# BENCHMARKS.md's counts; its output lands in target/release as well.
cargo build --profile bench --example period_instructions 2>/dev/null
bin=target/release/examples/period_instructions
count() {
    valgrind --tool=callgrind --callgrind-out-file=/dev/null "$bin" "$1" "$2" 2>&1 |
        awk '/Collected/ {print $4}'
}
for what in m2ps/linearised dense/18x6 m1pa/linearised dense/12x3; do
    a=$(count "$what" 1000)
    b=$(count "$what" 3000)
    echo "host-instructions $what $(( (b - a) / 2000 )) per period"
done

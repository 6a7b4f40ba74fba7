#!/usr/bin/env bash
# Prints every firmware number of BENCHMARKS.md:
#   - flash and static RAM of both builds (arm-none-eabi-size);
#   - peak stack (stack painting, logged by the firmware) and the size of
#     the filter/calibrator state (size_of, logged by the firmware);
#   - instructions per filter period (QEMU + tools/qemu-insnmark), counted
#     between markers around `Calibrator::push` (validation + predict +
#     update) on the recorded paper streams (M2-ps, M1-pa; Options::default()
#     and, with mode=plain, Options::plain()), and around `Filter::step` on
#     the synthetic motion (default, plain, linearised);
#   - the top functions of an M2-ps default period (per-function breakdown).
# Usage: firmware/bench.sh [--quick]   (--quick: synthetic counts only)
# Needs defmt-print for the logged numbers (cargo install --locked defmt-print).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
QUICK=${1:-}

ensure_tools
build_host
build_firmware
build_plugin

echo "## Sizes (arm-none-eabi-size; flash = text + data, static RAM = data + bss)"
for v in m4f m7; do
    elf=$M4F_ELF
    [ "$v" = m7 ] && elf=$M7_ELF
    arm-none-eabi-size "$elf" | awk -v v="$v" 'NR == 2 { printf "%s: flash %d bytes, static RAM %d bytes (text %d, data %d, bss %d)\n", v, $1 + $2, $2 + $3, $1, $2, $3 }'
done

counts() { grep '^insnmark:' "$1" | grep -v 'total insns' | sed 's/^insnmark: /    /'; }

echo
echo "## Instructions per period, synthetic motion (200 periods, Filter::step)"
for v in m4f m7; do
    for c in M2-ps M1-pa; do
        for m in default plain linearised; do
            echo "$v $c $m:"
            run_qemu "$v" /dev/null "$OUT/bench.reply" "$OUT/bench.defmt" \
                "source=synthetic config=$c mode=$m periods=200" "first=3" 2>"$OUT/bench.plugin" ||
                echo "    (exit status $?)"
            counts "$OUT/bench.plugin"
        done
    done
done

echo
echo "## Where an M2-ps default period goes (synthetic, top functions)"
for v in m4f m7; do
    echo "$v:"
    run_qemu "$v" /dev/null "$OUT/bench.reply" "$OUT/bench.defmt" \
        "source=synthetic config=M2-ps mode=default periods=50" "first=1,syms=12" 2>"$OUT/bench.plugin" || true
    grep '%' "$OUT/bench.plugin" | sed 's/^insnmark: /    /' | cut -c1-160
done

[ "$QUICK" = --quick ] && exit 0

echo
echo "## Instructions per period, recorded paper streams (seed 1, Calibrator::push)"
for c in M2-ps M1-pa; do
    record_stream "$c"
done
for v in m7 m4f; do
    elf=$M4F_ELF
    [ "$v" = m7 ] && elf=$M7_ELF
    for c in M2-ps M1-pa; do
        for m in default plain; do
            echo "$v $c $m:"
            rc=0
            run_qemu "$v" "$OUT/$c-in.bin" "$OUT/bench.reply" "$OUT/bench.defmt" \
                "exit=request reply=uart1 mode=$m" "first=3" 2>"$OUT/bench.plugin" || rc=$?
            counts "$OUT/bench.plugin"
            show_defmt "$elf" "$OUT/bench.defmt" | grep -E 'firmware:|stream done|peak stack' | sed 's/^/    /'
            [ "$rc" -eq 0 ] || echo "    (exit status $rc: samples rejected)"
        done
    done
done

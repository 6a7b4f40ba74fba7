#!/usr/bin/env bash
# Where a filter period's emulated f64 and memory copies go, by calling
# function: runs the firmware's synthetic motion under QEMU with
# tools/qemu-insnmark (`memcallers=…,softfloat=1`), then sums the
# instructions spent in the soft-float routines and in memcpy/memclr per
# period by the function that called them.
#
# Usage: tools/emulated-f64-by-caller.sh [VARIANT] [CONFIG] [MODE] [TOP]
#   VARIANT m4f (default) or m7; CONFIG e.g. M1-pa (default), M2-ps;
#   MODE linearised (default), default or plain; TOP rows (default 15).
# Builds the firmware as firmware/bench.sh does (target/m4f, target/m7).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../firmware/common.sh"
variant=${1:-m4f} config=${2:-M1-pa} mode=${3:-linearised} top=${4:-15}
periods=50
case $variant in m4f | m7) ;; *) echo "unknown variant '$variant' (m4f or m7)" >&2; exit 2 ;; esac
case $mode in linearised | default | plain) ;; *) echo "unknown mode '$mode' (linearised, default or plain)" >&2; exit 2 ;; esac
ensure_tools
build_firmware
build_plugin
plugin_log="$OUT/emulated-f64-$variant-$config-$mode.plugin"
run_qemu "$variant" /dev/null "$OUT/emulated-f64.reply" "$OUT/emulated-f64.defmt" \
    "source=synthetic config=$config mode=$mode periods=$periods noise_scale=1000" \
    "first=1,syms=0,memcallers=100000,softfloat=1" 2>"$plugin_log" || true
# The plugin's call-site lines: `insnmark: mem <share> <insns> <addr> <function>`.
grep '^insnmark: mem ' "$plugin_log" | sed 's/^insnmark: //' | arm-none-eabi-c++filt | python3 -c "
import collections, re, sys
by = collections.Counter()
for line in sys.stdin:
    parts = line.split(None, 4)
    if len(parts) == 5:
        by[re.sub(r'::h[0-9a-f]{16}\b', '', parts[4].strip())] += int(parts[2])
periods = $periods
total = sum(by.values())
if not total:
    sys.exit('no call sites counted: did the run reach its periods? see $plugin_log')
print(f'$variant $config $mode: {total / periods:.0f} instructions a period in soft-float and mem* routines, by caller:')
for name, n in by.most_common($top):
    print(f'{n / periods:8.0f}  {name[:110]}')
"

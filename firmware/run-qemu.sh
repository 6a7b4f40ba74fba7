#!/usr/bin/env bash
# Runs the firmware under QEMU, end to end, on the recorded paper streams and
# checks it against the host: installs qemu-system-arm if missing, builds the
# Cortex-M4F/f32 and Cortex-M7/f64 variants, records the M2-ps and M1-pa
# streams (seed 1) with `host-sim record`, appends EstimateRequest + Finish
# (`firmware-check end-frame`), feeds each stream to the firmware's UART0
# (QEMU `-serial stdio`, stdin redirected) and collects the Estimate frames
# from UART1. On Finish the firmware runs the estimator of record over its
# sample log (the LOG region of memory.x) and replies with the final
# estimate, which is compared with `host-sim calibrate` (default passes) on
# the same stream.
#
# M7/f64 runs, each of which fails the script (exit 1) when it does not hold:
#   M2-ps, M1-pa   QEMU exits 0 (no sample rejected or dropped, a final
#                  estimate of record sent), the final estimate is `Final`
#                  with the host's passes, every state within 1e-9 rad of
#                  the host's;
#   M2-ps with selftest=checkpoint-at=2700: checkpoint, Reset and restore
#                  mid-run (the log stays in RAM); every Estimate frame,
#                  the final one included, bit-identical to the
#                  uninterrupted M2-ps run's;
#   M2-ps with its first frame (Configure) garbled: the samples are dropped
#                  and nothing is logged; the firmware must exit with 3.
# M4F/f32 runs (M2-ps, M1-pa), each of which fails the script when it does
# not hold: QEMU exits 0, the final estimate is `Final` with the host's
# passes, and every state is within 0.1σ of the host's f64 answer (the
# factored filter's covariance arithmetic in f32, its nominal in f64); each
# gets at most QEMU_TIMEOUT_F32 s (default 900) on the second core while
# the M7 runs go on.
#
# Ends with one `summary build=… config=… passes=… max_dabs_rad=…
# max_dsigma=… limit=… ok|FAIL` line per run.
#
# Usage: firmware/run-qemu.sh        (outputs in target/firmware/)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

CHECKPOINT_AT=2700
SUMMARY="$OUT/summary.txt"

ensure_tools
build_host
build_firmware
for config in M2-ps M1-pa; do
    log "recording the paper stream for $config (seed 1); host-sim calibrate (default passes)"
    record_stream "$config"
    "$HOST_SIM" calibrate --config "$config" --input "$OUT/$config.bin" \
        --json "$OUT/host-$config.json" >"$OUT/host-$config.txt" 2>&1
done
log "the M2-ps stream with its Configure frame garbled"
"$FW_CHECK" garble-first-frame --input "$OUT/M2-ps-in.bin" --out "$OUT/M2-ps-noconf-in.bin"

# run_one VARIANT INPUT NAME APPEND: runs QEMU, shows the end of the defmt
# log, leaves $OUT/NAME.out (replies), $OUT/NAME.rc and $OUT/NAME.seconds.
run_one() {
    local variant=$1 input=$2 name=$3 append=$4 rc=0 start elf=$M4F_ELF
    [ "$variant" = m7 ] && elf=$M7_ELF
    start=$(date +%s)
    run_qemu "$variant" "$input" "$OUT/$name.out" "$OUT/$name.defmt" "$append" || rc=$?
    echo "$rc" >"$OUT/$name.rc"
    echo "$(($(date +%s) - start))" >"$OUT/$name.seconds"
    {
        echo "--- $name: QEMU exit status $rc after $(cat "$OUT/$name.seconds") s; end of its log:"
        show_defmt "$elf" "$OUT/$name.defmt" | grep -v 'rejected: Filter' | tail -n 5 || true
    } >&2
}

# The f32 runs, in the background (their output is shown after the M7 runs).
log "QEMU M4F/f32 on M2-ps and M1-pa, in the background (at most ${QEMU_TIMEOUT_F32:-900} s each)"
(
    export QEMU_TIMEOUT=${QEMU_TIMEOUT_F32:-900}
    for config in M2-ps M1-pa; do
        run_one m4f "$OUT/$config-in.bin" "m4f-$config" "exit=request reply=uart1"
    done
) 2>"$OUT/m4f.log" &
f32_job=$!

status=0
: >"$SUMMARY"
for config in M2-ps M1-pa; do
    log "QEMU M7/f64 on $config"
    run_one m7 "$OUT/$config-in.bin" "m7-$config" "exit=request reply=uart1"
    "$FW_CHECK" compare --label "M7/f64 $config" --tol 1e-9 \
        --firmware "$OUT/m7-$config.out" --host "$OUT/host-$config.json" \
        --build M7/f64 --config "$config" --rc "$(cat "$OUT/m7-$config.rc")" \
        --seconds "$(cat "$OUT/m7-$config.seconds")" | tee -a "$SUMMARY" || status=1
done

log "QEMU M7/f64 on M2-ps: checkpoint, Reset, restore after sample $CHECKPOINT_AT"
name=m7-M2-ps-checkpoint
run_one m7 "$OUT/M2-ps-in.bin" "$name" "exit=request reply=uart1 selftest=checkpoint-at=$CHECKPOINT_AT"
"$FW_CHECK" identical --firmware "$OUT/$name.out" --reference "$OUT/m7-M2-ps.out" \
    --against uninterrupted --build M7/f64 --config "M2-ps+checkpoint-at=$CHECKPOINT_AT" \
    --rc "$(cat "$OUT/$name.rc")" --seconds "$(cat "$OUT/$name.seconds")" | tee -a "$SUMMARY" || status=1

log "QEMU M7/f64 on M2-ps without its Configure frame (must fail with exit status 3)"
name=m7-M2-ps-noconf
run_one m7 "$OUT/M2-ps-noconf-in.bin" "$name" "exit=request reply=uart1"
rc=$(cat "$OUT/$name.rc")
line="summary build=M7/f64 config=M2-ps/Configure-lost expect=exit-3 exit=$rc qemu=$(cat "$OUT/$name.seconds")s"
if [ "$rc" -eq 3 ]; then
    echo "$line ok (samples before any Configure dropped, no final estimate)" | tee -a "$SUMMARY"
else
    echo "$line FAIL (a stream whose Configure was lost must end with exit status 3)" | tee -a "$SUMMARY"
    status=1
fi

log "waiting for the M4F/f32 runs"
wait "$f32_job" || true
cat "$OUT/m4f.log" >&2
for config in M2-ps M1-pa; do
    "$FW_CHECK" compare --label "M4F/f32 $config" --tol-sigma 0.1 \
        --firmware "$OUT/m4f-$config.out" --host "$OUT/host-$config.json" \
        --build M4F/f32 --config "$config" --rc "$(cat "$OUT/m4f-$config.rc")" \
        --seconds "$(cat "$OUT/m4f-$config.seconds")" | tee -a "$SUMMARY" || status=1
done

echo
echo "==> firmware under QEMU: one line per run"
grep '^summary ' "$SUMMARY"
if [ "$status" -ne 0 ]; then
    echo "FAIL: a firmware check failed (see above)" >&2
fi
exit $status

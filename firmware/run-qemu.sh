#!/usr/bin/env bash
# Runs the firmware under QEMU, end to end, on recorded streams and checks it
# against the host: installs qemu-system-arm if missing, builds the
# Cortex-M4F/f32 and Cortex-M7/f64 variants (every configuration, the full
# model), records four streams with `host-sim record` (seed 1): M2-ps and
# M1-pa on the paper's scenario with the installation model, and on the
# realistic scenario (the instruments' own errors, k2 and the errors that
# wander) with the full model;
# appends EstimateRequest + Finish (`firmware-check end-frame`), feeds each
# stream to the firmware's UART0 (QEMU `-serial stdio`, stdin redirected) and
# collects the Estimate frames from UART1. The firmware logs every period in
# its sample log, `FlashLog` over a NOR flash device on the SSRAM
# (firmware/src/flash.rs), through the integration kit (rollcal::device,
# firmware/src/stream.rs); on Finish it runs the estimator of record over
# the log and replies with the final estimate, which is compared with
# `host-sim calibrate --log packed` (default passes, f64, the records
# rounded as the flash log stores them) on the same stream.
#
# M7/f64 runs, each of which fails the script (exit 1) when it does not hold:
#   M2-ps, M1-pa, installation and full model:
#                  QEMU exits 0 (no sample rejected or dropped, a final
#                  estimate of record sent), the final estimate is `Final`
#                  with the host's passes, every installation state within
#                  1e-9 rad of the host's and every instrument term of the
#                  full model within 1e-6 of its σ;
#   M2-ps, full model, with selftest=checkpoint-at=2700: CheckpointRequest,
#                  Reset and the checkpoint back, as a host sends them,
#                  mid-run; every Estimate frame, the final one included,
#                  bit-identical to the uninterrupted run's;
#   M2-ps, full model, with selftest=reset-at=2850: the device started
#                  again on the flash alone mid-run (the kit resumes the
#                  configuration, the checkpoint of sample 2707 and the
#                  records after it); the final estimate's state and σ
#                  bit-identical to the uninterrupted run's, the running
#                  ones after the reset within 0.01σ (the replayed records
#                  are the packed log's, rounded);
#   M2-ps with its first frame (Configure) garbled: the samples are dropped
#                  and nothing is logged; the firmware must exit with 3.
# M4F/f32 runs (M2-ps, M1-pa; installation and full model), each of which
# fails the script when it does not hold: QEMU exits 0, the final estimate is
# `Final` with the host's passes, and every state is within 0.1σ of the
# host's f64 answer (the factored filter's covariance arithmetic in f32, its
# nominal in f64); each gets at most QEMU_TIMEOUT_F32 s (default 1200) on
# the second core while the M7 runs go on.
#
# Ends with one `summary build=… config=… errors=… passes=… max_dabs_rad=…
# max_dsigma=… limit=… ok|FAIL` line per run.
#
# Usage: firmware/run-qemu.sh        (outputs in target/firmware/)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

CHECKPOINT_AT=2700
# Not a checkpoint's sample: the resumed device replays the records after
# the last one (the kit checkpoints every 300 samples).
RESET_AT=2850
SUMMARY="$OUT/summary.txt"
# The streams: <config> (paper scenario, installation model) and
# <config>-full (realistic scenario, full model).
STREAMS=(M2-ps M1-pa M2-ps-full M1-pa-full)

ensure_tools
build_host
build_firmware
for stream in "${STREAMS[@]}"; do
    config=${stream%-full}
    log "recording the stream $stream (seed 1); host-sim calibrate --log packed (default passes)"
    if [ "$stream" = "$config" ]; then record_stream "$config"; else record_stream "$config" full; fi
    "$HOST_SIM" calibrate --config "$config" --input "$OUT/$stream.bin" --log packed \
        --json "$OUT/host-$stream.json" >"$OUT/host-$stream.txt" 2>&1
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
        show_defmt "$elf" "$OUT/$name.defmt" | grep -v 'rejected: Filter' | tail -n 6 || true
    } >&2
}

# compare_one VARIANT STREAM BUILD TOLERANCE...: the run's last estimate
# against the host's, its summary line appended to $SUMMARY.
compare_one() {
    local variant=$1 stream=$2 build=$3
    shift 3
    "$FW_CHECK" compare --label "$build $stream" "$@" \
        --firmware "$OUT/$variant-$stream.out" --host "$OUT/host-$stream.json" \
        --build "$build" --config "${stream%-full}" --rc "$(cat "$OUT/$variant-$stream.rc")" \
        --seconds "$(cat "$OUT/$variant-$stream.seconds")" | tee -a "$SUMMARY"
}

# The f32 runs, in the background (their output is shown after the M7 runs).
log "QEMU M4F/f32 on ${STREAMS[*]}, in the background (at most ${QEMU_TIMEOUT_F32:-1200} s each)"
(
    export QEMU_TIMEOUT=${QEMU_TIMEOUT_F32:-1200}
    for stream in "${STREAMS[@]}"; do
        run_one m4f "$OUT/$stream-in.bin" "m4f-$stream" "exit=request reply=uart1"
    done
) 2>"$OUT/m4f.log" &
f32_job=$!

status=0
: >"$SUMMARY"
for stream in "${STREAMS[@]}"; do
    log "QEMU M7/f64 on $stream"
    run_one m7 "$OUT/$stream-in.bin" "m7-$stream" "exit=request reply=uart1"
    compare_one m7 "$stream" M7/f64 --tol 1e-9 || status=1
done

log "QEMU M7/f64 on M2-ps-full: CheckpointRequest, Reset and the checkpoint back after sample $CHECKPOINT_AT"
name=m7-M2-ps-full-checkpoint
run_one m7 "$OUT/M2-ps-full-in.bin" "$name" "exit=request reply=uart1 selftest=checkpoint-at=$CHECKPOINT_AT"
"$FW_CHECK" identical --firmware "$OUT/$name.out" --reference "$OUT/m7-M2-ps-full.out" \
    --against uninterrupted --build M7/f64 --config "M2-ps-full+checkpoint-at=$CHECKPOINT_AT" \
    --rc "$(cat "$OUT/$name.rc")" --seconds "$(cat "$OUT/$name.seconds")" | tee -a "$SUMMARY" || status=1

log "QEMU M7/f64 on M2-ps-full: a reset after sample $RESET_AT, the device resumed from the flash alone"
name=m7-M2-ps-full-reset
run_one m7 "$OUT/M2-ps-full-in.bin" "$name" "exit=request reply=uart1 selftest=reset-at=$RESET_AT"
"$FW_CHECK" identical --firmware "$OUT/$name.out" --reference "$OUT/m7-M2-ps-full.out" \
    --against uninterrupted --final-only-running-sigma 0.01 --build M7/f64 \
    --config "M2-ps-full+reset-at=$RESET_AT" \
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
for stream in "${STREAMS[@]}"; do
    compare_one m4f "$stream" M4F/f32 --tol-sigma 0.1 || status=1
done

echo
echo "==> firmware under QEMU: one line per run"
grep '^summary ' "$SUMMARY"
if [ "$status" -ne 0 ]; then
    echo "FAIL: a firmware check failed (see above)" >&2
fi
exit $status

#!/usr/bin/env bash
# The frame layer's figures (BENCHMARKS.md §The frame layer): the flash of
# the one-configuration M2-ps flight images (M4F f32, M7 f64; text + data)
# and the instructions per frame of `wire::encode` and of the decoder
# (`FrameDecoder::push_byte_into`, every byte of the frame, delimiter
# included) for a Sample, an Estimate and a Checkpoint (18 states), counted
# under QEMU by tools/qemu-insnmark between rollcal_mark_frame_start and
# _end (the firmware's `source=frames` run, firmware/src/frames.rs, in
# images built with the cargo feature frame-bench: the flight images do
# not hold it).
# Prints `figure frame-…` lines (bench.sh adds them to its goals).
# Usage: firmware/frames.sh
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

ensure_tools
build_plugin
read -r FLIGHT_M4F FLIGHT_M7 < <(build_firmware_one config-m2ps,installation-model)
echo "figure frame-flash-m4f-m2ps $(flash_bytes "$FLIGHT_M4F") bytes"
echo "figure frame-flash-m7-m2ps $(flash_bytes "$FLIGHT_M7") bytes"
# run_qemu runs $M4F_ELF / $M7_ELF: here the images with the self-measurement.
read -r M4F_ELF M7_ELF < <(build_firmware_one config-m2ps,installation-model,frame-bench)

for v in m4f m7; do
    elf=$M4F_ELF
    [ "$v" = m7 ] && elf=$M7_ELF
    deltas="$OUT/frames-$v.txt"
    rc=0
    MARK=frame run_qemu "$v" /dev/null "$OUT/frames.reply" "$OUT/frames.defmt" \
        "source=frames" "first=1,out=$deltas" 2>"$OUT/frames.plugin" || rc=$?
    if [ "$rc" -ne 0 ]; then
        echo "frames run on $v failed (exit status $rc)" >&2
        show_defmt "$elf" "$OUT/frames.defmt" >&2
        exit 1
    fi
    # The regions in order: per message, REPS encodes then REPS decodes
    # (firmware/src/frames.rs); the figure is the last repetition's (they
    # differ by a few instructions of the loop around them; more than 10 + 0.1 %
    # is an error).
    reps=$(sed -nE 's/^ *pub const REPS: usize = ([0-9]+);/\1/p' "$FW/src/frames.rs")
    awk -v v="$v" -v reps="$reps" '
        BEGIN { split("sample estimate checkpoint", msg, " "); split("encode decode", op, " ") }
        {
            k = int((NR - 1) / reps)
            name = msg[int(k / 2) + 1] "-" op[k % 2 + 1]
            if (!(name in n)) order[++m] = name
            if (!(name in lo) || $1 < lo[name]) lo[name] = $1
            if (!(name in hi) || $1 > hi[name]) hi[name] = $1
            n[name] = $1
        }
        END {
            if (NR != 6 * reps) { print "expected " 6 * reps " regions, got " NR > "/dev/stderr"; exit 1 }
            for (i = 1; i <= m; i++) {
                x = order[i]
                if (hi[x] - lo[x] > 10 + n[x] / 1000) { print x ": repetitions differ (" lo[x] " to " hi[x] ")" > "/dev/stderr"; exit 1 }
                printf "figure frame-insns-%s-%s %s instructions\n", v, x, n[x]
            }
        }' "$deltas"
done

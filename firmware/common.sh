# Shared by run-qemu.sh and bench.sh (sourced, not run).
# Builds the two firmware variants and runs them under QEMU.

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
FW="$ROOT/firmware"
OUT="${FIRMWARE_OUT:-$ROOT/target/firmware}"
THUMB=thumbv7em-none-eabihf
M4F_ELF="$FW/target/m4f/$THUMB/release/rollcal-firmware"
M7_ELF="$FW/target/m7/$THUMB/release/rollcal-firmware"
HOST_SIM="$ROOT/target/release/host-sim"
FW_CHECK="$ROOT/target/release/firmware-check"
PLUGIN="$OUT/libinsnmark.so"
mkdir -p "$OUT"

log() { printf '==> %s\n' "$*" >&2; }

# Installs qemu-system-arm and binutils-arm-none-eabi if missing (Debian/Ubuntu).
ensure_tools() {
    local missing=()
    command -v qemu-system-arm >/dev/null || missing+=(qemu-system-arm)
    command -v arm-none-eabi-size >/dev/null || missing+=(binutils-arm-none-eabi)
    if ((${#missing[@]})); then
        local sudo=()
        [ "$(id -u)" -eq 0 ] || sudo=(sudo)
        log "installing ${missing[*]}"
        "${sudo[@]}" apt-get install -y "${missing[@]}" >/dev/null ||
            { "${sudo[@]}" apt-get update >/dev/null && "${sudo[@]}" apt-get install -y "${missing[@]}" >/dev/null; }
    fi
    rustup target add "$THUMB" >/dev/null 2>&1 || true
}

# Both variants, in separate target directories, each with every
# configuration, the research options and the full model:
#   m4f: Cortex-M4F, estimator in f32 (default CPU of the target: single-precision FPU);
#   m7:  Cortex-M7 (-C target-cpu=cortex-m7: double-precision FPU), estimator in f64.
build_firmware() {
    log "building firmware (M4F f32, M7 f64)"
    (cd "$FW" && DEFMT_LOG=info cargo build --release --features full-model --target-dir target/m4f)
    (cd "$FW" && DEFMT_LOG=info RUSTFLAGS="-C target-cpu=cortex-m7" \
        cargo build --release --no-default-features --features f64,all-configs,research-options,installation-model,full-model,selftest,synthetic --target-dir target/m7)
    # The M7 build must use the double FPU, not soft-float calls.
    local n
    n=$(arm-none-eabi-objdump -d "$M7_ELF" | grep -c 'vmul\.f64' || true)
    if [ "$n" -eq 0 ]; then
        echo "M7 build has no vmul.f64: not built for the Cortex-M7's double FPU" >&2
        return 1
    fi
}

# build_firmware_one FEATURES [OPT_LEVEL]: both variants with one
# configuration, FEATURES the cargo features of firmware/Cargo.toml besides
# the scalar (e.g. config-m2ps,installation-model: a flight image of the
# installation model; config-m2ps,full-model: of the full model alone), at
# the release profile (opt-level 3) or at OPT_LEVEL (e.g. s); in
# target/{m4f,m7}-one-TAG; prints the two ELF paths (M4F, then M7), copied
# to $OUT/{m4f,m7}-TAG.elf.
build_firmware_one() {
    local features=$1 opt=${2:-} tag
    tag=$(echo "$features" | tr ',' '+')${opt:+-opt-$opt}
    local env=(DEFMT_LOG=info)
    [ -n "$opt" ] && env+=(CARGO_PROFILE_RELEASE_OPT_LEVEL="$opt")
    log "building firmware with one configuration ($features${opt:+, opt-level $opt})"
    (cd "$FW" && env "${env[@]}" cargo build --release --no-default-features \
        --features "f32,$features" --target-dir "target/m4f-one-$tag") >&2
    cp "$FW/target/m4f-one-$tag/$THUMB/release/rollcal-firmware" "$OUT/m4f-$tag.elf"
    (cd "$FW" && env "${env[@]}" RUSTFLAGS="-C target-cpu=cortex-m7" cargo build --release \
        --no-default-features --features "f64,$features" --target-dir "target/m7-one-$tag") >&2
    cp "$FW/target/m7-one-$tag/$THUMB/release/rollcal-firmware" "$OUT/m7-$tag.elf"
    echo "$OUT/m4f-$tag.elf" "$OUT/m7-$tag.elf"
}

# flash_bytes ELF: text + data (what the image puts in flash).
flash_bytes() { arm-none-eabi-size "$1" | awk 'NR == 2 { print $1 + $2 }'; }

build_host() {
    log "building host-sim"
    (cd "$ROOT" && cargo build --release -p host-sim --bins)
}

build_plugin() {
    gcc -shared -fPIC -O2 -o "$PLUGIN" "$ROOT/tools/qemu-insnmark/insnmark.c"
}

# record_stream CONFIG [full]: records a stream (seed 1) and appends the
# end-of-stream frames (EstimateRequest, Finish): the paper scenario with
# the installation model, $OUT/<config>.bin (stream) and $OUT/<config>-in.bin
# (firmware input); with `full`, the realistic scenario (the instruments'
# own errors, k2 and the errors that wander, docs/model.md §Errors that
# wander) with the full model, $OUT/<config>-full.bin and
# $OUT/<config>-full-in.bin.
record_stream() {
    local config=$1 name=$1 args=()
    if [ "${2:-}" = full ]; then
        name=$config-full
        args=(--errors full --scenario "$ROOT/scenarios/realistic.toml")
    fi
    "$HOST_SIM" record --config "$config" --seed 1 "${args[@]}" --out "$OUT/$name.bin" 2>/dev/null
    "$FW_CHECK" end-frame >"$OUT/$name-end.bin"
    cat "$OUT/$name.bin" "$OUT/$name-end.bin" >"$OUT/$name-in.bin"
}

marker() { arm-none-eabi-nm "$1" | awk -v s="$2" '$3 == s { print "0x" $1 }'; }

# run_qemu VARIANT INPUT REPLY_FILE DEFMT_FILE APPEND [PLUGIN_ARGS]
# VARIANT m4f (mps2-an386, cortex-m4) or m7 (mps2-an500, cortex-m7). With
# PLUGIN_ARGS, the plugin counts between the markers rollcal_mark_${MARK}_start
# and _end (MARK=period by default; MARK=finish: the estimator of record). UART0
# reads INPUT (stdin), UART1 writes REPLY_FILE, defmt (semihosting) goes to
# DEFMT_FILE, the plugin's report to stderr. Returns QEMU's exit status (the
# firmware's semihosting exit code; 124 on timeout).
run_qemu() {
    local variant=$1 input=$2 reply=$3 defmt=$4 append=$5 plugin_args=${6:-}
    local machine cpu elf
    case $variant in
        m4f) machine=mps2-an386 cpu=cortex-m4 elf=$M4F_ELF ;;
        m7) machine=mps2-an500 cpu=cortex-m7 elf=$M7_ELF ;;
        *) echo "unknown variant $variant" >&2; return 2 ;;
    esac
    local plugin=()
    if [ -n "$plugin_args" ]; then
        local m=${MARK:-period}
        plugin=(-plugin "$PLUGIN,start=$(marker "$elf" "rollcal_mark_${m}_start"),end=$(marker "$elf" "rollcal_mark_${m}_end"),$plugin_args" -d plugin)
    fi
    timeout "${QEMU_TIMEOUT:-600}" qemu-system-arm -machine "$machine" -cpu "$cpu" \
        -nographic -monitor none \
        -semihosting-config enable=on,target=native \
        -kernel "$elf" -append "$append" \
        -serial stdio -serial "file:$reply" \
        "${plugin[@]}" <"$input" >"$defmt"
}

# Prints the defmt log of ELF from FILE (needs defmt-print; else says so).
show_defmt() {
    if command -v defmt-print >/dev/null; then
        defmt-print -e "$1" <"$2" || true
    else
        echo "(defmt-print not installed: raw defmt log kept in $2; cargo install --locked defmt-print)"
    fi
}

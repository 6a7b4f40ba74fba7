#!/usr/bin/env python3
"""Where the flash of a firmware image goes, by area of the code.

Usage: tools/flash-by-area.py ELF [--top N]

Sums the sizes of the image's symbols that live in flash (code, read-only
data, initialised data: `arm-none-eabi-nm` types t, r, d) by the area their
demangled name belongs to (the estimator's filter, its model, the
multi-pass estimator and calibrator, the wire protocol and session, the
math libraries, the firmware itself), prints one line per area with its
bytes and share, then the N largest functions (default 10). A generic
function is counted where it is instantiated: `rollcal::ekf::Filter<f32,
M1Pa>::whiten` is the filter's, whichever crate instantiated it. The total
is the symbols' sum; `arm-none-eabi-size` also counts the alignment padding
and the sections without symbols, a few hundred bytes more.
"""
import re
import subprocess
import sys

# (area, pattern on the demangled name with impl/trait wrappers removed),
# first match wins.
AREAS = [
    ("filter (ekf, factor)", r"^rollcal::(ekf::(?!second_order::)|factor::)"),
    ("model (models, geometry, command, second_order, trig)",
     r"^rollcal::(models|geometry|command|ekf::second_order|second_order|trig|instruments|precision)::"),
    ("multi-pass estimator, calibrator", r"^rollcal::(estimator|calibrator)::"),
    ("wire protocol, session (incl. serde, postcard, heapless)",
     r"^(rollcal::(wire|session)|postcard|serde|serde_core|heapless)::"),
    ("math libraries (libm, soft-float, nalgebra)",
     r"^(libm|compiler_builtins::float|nalgebra|__aeabi_[dfi]|__aeabi_[ul]2[df])"),
    ("firmware (stream, main, runtime, defmt, semihosting)",
     r"^(rollcal_firmware|cortex_m|cortex_m_rt|cortex_m_semihosting|defmt|_defmt|__INTERRUPTS|__RESET|Reset|__pre_init|HardFault|DefaultHandler|main$)"),
    ("core, memcpy, integer division", r"^(core|compiler_builtins|__aeabi_mem|__aeabi_ul|__aeabi_ui|__aeabi_l|memcpy|memset|memmove|memcmp)"),
]


def strip(name: str) -> str:
    """The path a symbol belongs to: `<A as B>::f` is `A`'s, `&mut` dropped."""
    name = name.strip()
    while True:
        m = re.match(r"^<(&(mut )?)?(.*?)( as [^>]*)?>::(.*)$", name)
        if not m:
            break
        name = m.group(3) + "::" + m.group(5)
    return name.lstrip("&")


def main() -> int:
    args = sys.argv[1:]
    if not args or args[0] in ("-h", "--help"):
        print(__doc__.strip())
        return 0 if args else 2
    elf = args[0]
    top = 10
    if "--top" in args:
        try:
            top = int(args[args.index("--top") + 1])
        except (IndexError, ValueError):
            print("flash-by-area: --top needs a number", file=sys.stderr)
            return 2
    try:
        out = subprocess.run(
            ["arm-none-eabi-nm", "--size-sort", "-S", "-C", elf],
            capture_output=True, text=True, check=True,
        ).stdout
    except (OSError, subprocess.CalledProcessError) as e:
        print(f"flash-by-area: cannot read {elf}: {e}", file=sys.stderr)
        return 1
    sums = {area: 0 for area, _ in AREAS}
    other = 0
    functions = []
    for line in out.splitlines():
        parts = line.split(None, 3)
        if len(parts) < 4 or parts[2].lower() not in "trd":
            continue
        size = int(parts[1], 16)
        name = strip(parts[3])
        for area, pattern in AREAS:
            if re.search(pattern, name):
                sums[area] += size
                break
        else:
            other += size
        if parts[2].lower() == "t":
            functions.append((size, parts[3].strip()))
    total = sum(sums.values()) + other
    print(f"flash by area ({elf.split('/')[-1]}, symbols' sum {total} bytes)")
    for area, _ in AREAS:
        print(f"  {sums[area]:7d} B {100 * sums[area] / max(total, 1):5.1f} %  {area}")
    print(f"  {other:7d} B {100 * other / max(total, 1):5.1f} %  other (unnamed constants)")
    print(f"largest {top} functions:")
    for size, name in sorted(functions, reverse=True)[:top]:
        name = re.sub(r"::h[0-9a-f]{16}$", "", name)
        print(f"  {size:7d} B  {name[:110]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

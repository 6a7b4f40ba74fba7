#!/usr/bin/env python3
"""Panic paths reachable from the estimator's entry points, from the binary.

Usage: tools/panic-check.py ELF [--entry REGEX]... [--panic REGEX]...
                            [--indirect report|address-taken] [--quiet]

Builds the static call graph of a Thumb-2 ELF from
`arm-none-eabi-objdump -d --demangle`: an edge for every direct branch to
another function (`bl`, `blx <imm>`, `b`/`b.w`/`b.n` and the conditional
branches: tail calls), by target address (one node per function address, so
the seven monomorphisations of a generic function are seven nodes). From the
entry points (functions whose demangled name matches an `--entry` regex; the
defaults are the calibrator's, the filter's and the session's public
operations) it walks the graph breadth first, without entering panicking
functions (names matching a `--panic` regex: `core::panicking`, bounds and
slice-index failures, `unwrap_failed`, `expect_failed`, `assert_failed`,
`panic_fmt`, the `#[panic_handler]`, …).

A *panicking call* is a call site (a branch instruction) in a reachable,
non-panicking function whose target is a panicking one. Every one is printed with one shortest chain from an entry
point, the call site's address and, from the DWARF line table
(`arm-none-eabi-addr2line -i`), the source lines of the call site with the
frames inlined into it (the firmware is built with `debug = 2`).

Indirect calls (`blx rN`, `bx rN` other than `bx lr`, `mov pc, rN`, loads
into pc) have no static target. With `--indirect report` (default) every
reachable one is listed as an unknown edge and not followed: the result then
covers the direct call graph only, and the tool says so. With
`--indirect address-taken` every indirect call may reach any function whose
address (with the Thumb bit) appears as a word in a data section or a
literal pool: a sound over-approximation (vtables, function pointers).

Exit status: 0 when no panicking call is reachable (it prints
`panic-check: 0 reachable panicking calls from N entry points (M functions)`),
1 when some are (0 with the environment variable PANIC_CHECK_ALLOW_FAIL=1:
report only), 2 when the ELF cannot be read or no entry point matched.
"""
import argparse
import bisect
import collections
import os
import re
import subprocess
import sys

DEFAULT_ENTRIES = [
    # An inherent impl in a submodule demangles as `rollcal::ekf::step::<impl
    # rollcal::ekf::Filter<T,M,_,_>>::step`: each pattern takes both forms.
    r"^rollcal::calibrator::(\w+::)*(<impl rollcal::calibrator::)?Calibrator<.*>::(new|push|push_logged|finish|checkpoint|restore|reset|estimate)$",
    r"^rollcal::ekf::(\w+::)*(<impl rollcal::ekf::)?Filter<.*>::(step|predict|update|new|from_parts|reacquire_attitude)$",
    r"^rollcal::session::(\w+::)*(<impl rollcal::session::)?Session<.*>::(handle|act|sample|finish|checkpoint|configure)$",
    r"^rollcal::session::(\w+::)*(<impl rollcal::session::)?AnyCalibrator<.*>::",
    r"^rollcal::session::(\w+::)*restore_into$",
]

DEFAULT_PANICS = [
    r"^core::panicking::",
    r"panic_bounds_check",
    r"unwrap_failed",
    r"expect_failed",
    r"slice_.*_fail",
    r"slice_index.*fail",
    r"len_mismatch_fail",
    r"panic_fmt",
    r"panic_const",
    r"panic_nounwind",
    r"panic_misaligned",
    r"assert_failed",
    r"rust_begin_unwind",
    r"__defmt_default_panic",
    r"^core::cell::panic_already",
    r"^core::result::unwrap_failed",
    r"^core::option::(unwrap|expect)_failed",
]

HEAD = re.compile(r"^([0-9a-f]+) <(.*)>:$")
INSN = re.compile(r"^\s*([0-9a-f]+):\t(\S+)(?:\t(.*))?$")
TARGET = re.compile(r"^([0-9a-f]+) <")
BRANCH = re.compile(r"^(bl|blx|b|cbz|cbnz|b(eq|ne|cs|hs|cc|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le|al))(\.[nw])?$")
HASH = re.compile(r"::h[0-9a-f]{16}$")


def tool(name, args, stdin=None):
    return subprocess.run([name] + args, input=stdin, capture_output=True, text=True, check=True).stdout


def short(name):
    return HASH.sub("", name)


def parse(elf):
    """Functions (address → name), direct edges, indirect call sites, literal words."""
    dis = tool("arm-none-eabi-objdump", ["-d", "--demangle", "--no-show-raw-insn", elf])
    names = {}
    edges = collections.defaultdict(list)  # caller address → [(callee address, site)]
    indirect = collections.defaultdict(list)  # caller address → [(site, insn)]
    words = set()
    cur = None
    for line in dis.splitlines():
        m = HEAD.match(line)
        if m:
            cur = int(m.group(1), 16)
            names[cur] = short(m.group(2))
            continue
        if cur is None:
            continue
        m = INSN.match(line)
        if not m:
            continue
        site, op, args = int(m.group(1), 16), m.group(2), (m.group(3) or "").strip()
        if op == ".word":
            w = re.match(r"0x([0-9a-f]+)", args)
            if w:
                words.add(int(w.group(1), 16))
            continue
        if op in ("cbz", "cbnz"):
            args = args.split(",", 1)[-1].strip()
        if BRANCH.match(op):
            t = TARGET.match(args)
            if t:
                edges[cur].append((int(t.group(1), 16), site))
                continue
            if re.match(r"^(r\d+|ip|sl|fp|sb)$", args) and not (op == "bx" and args == "lr"):
                indirect[cur].append((site, f"{op} {args}"))
            continue
        if op == "bx" and args != "lr":
            indirect[cur].append((site, f"{op} {args}"))
        elif op.startswith("mov") and re.match(r"^pc,", args):
            indirect[cur].append((site, f"{op} {args}"))
        elif op.startswith("ldr") and re.match(r"^pc,", args):
            indirect[cur].append((site, f"{op} {args}"))
    return names, edges, indirect, words


def data_words(elf):
    """32-bit little-endian words of the allocated, non-executable sections."""
    out = set()
    hdr = tool("arm-none-eabi-objdump", ["-h", elf])
    secs = []
    lines = hdr.splitlines()
    for i, line in enumerate(lines):
        f = line.split()
        if len(f) >= 7 and f[0].isdigit():
            flags = lines[i + 1] if i + 1 < len(lines) else ""
            if "ALLOC" in flags and "CODE" not in flags and "CONTENTS" in flags:
                secs.append(f[1])
    for s in secs:
        dump = tool("arm-none-eabi-objdump", ["-s", "-j", s, elf])
        blob = bytearray()
        for line in dump.splitlines():
            m = re.match(r"^ ([0-9a-f]+) ((?:[0-9a-f]{2,8} ?){1,4})", line)
            if m:
                blob += bytes.fromhex(m.group(2).replace(" ", ""))
        for k in range(0, len(blob) - 3):
            out.add(int.from_bytes(blob[k:k + 4], "little"))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("elf")
    ap.add_argument("--entry", action="append", help="entry-point regex (repeatable; replaces the defaults)")
    ap.add_argument("--panic", action="append", help="panicking-function regex (repeatable; added to the defaults)")
    ap.add_argument("--indirect", choices=("report", "address-taken"), default="report")
    ap.add_argument("--quiet", action="store_true", help="no call-site source lines")
    a = ap.parse_args()
    entry_res = [re.compile(p) for p in (a.entry or DEFAULT_ENTRIES)]
    panic_res = [re.compile(p) for p in DEFAULT_PANICS + (a.panic or [])]

    try:
        names, edges, indirect, words = parse(a.elf)
    except (OSError, subprocess.CalledProcessError) as e:
        err = getattr(e, "stderr", "") or str(e)
        print(f"panic-check: cannot disassemble {a.elf}: {err.strip()}", file=sys.stderr)
        return 2
    starts = sorted(names)

    def owner(addr):
        i = bisect.bisect_right(starts, addr) - 1
        return starts[i] if i >= 0 else None

    def is_panic(f):
        return any(p.search(names[f]) for p in panic_res)

    entries = [f for f in starts if any(p.search(names[f]) for p in entry_res)]
    unmatched = [p.pattern for p in entry_res if not any(p.search(names[f]) for f in starts)]
    for p in unmatched:
        print(f"panic-check: note: no function matches entry regex {p!r} (inlined into its callers?)")
    if not entries:
        print("panic-check: no entry point matched: nothing checked", file=sys.stderr)
        return 2

    taken = set()
    if a.indirect == "address-taken":
        ws = words | data_words(a.elf)
        taken = {f for f in starts if (f | 1) in ws}

    # Breadth first from all entries: parent links give one shortest chain each.
    parent = {f: None for f in entries}
    queue = collections.deque(entries)
    calls = {}  # (caller, panicking callee, call site) → None
    indirect_seen = []
    while queue:
        f = queue.popleft()
        succ = []
        for tgt, site in edges.get(f, ()):
            g = owner(tgt)
            if g is None or g == f:
                continue
            succ.append((g, site))
        if indirect.get(f):
            indirect_seen.extend((f, s, i) for s, i in indirect[f])
            succ.extend((g, s) for g in sorted(taken) for s, _ in indirect[f][:1])
        for g, site in succ:
            if is_panic(g):
                calls[(f, g, site)] = None
                continue
            if g not in parent:
                parent[g] = f
                queue.append(g)

    def chain(f):
        out = []
        while f is not None:
            out.append(f)
            f = parent[f]
        return out[::-1]

    sources = {}
    if calls and not a.quiet:
        sites = sorted({s for _, _, s in calls})
        try:
            txt = tool("arm-none-eabi-addr2line", ["-i", "-f", "-C", "-a", "-e", a.elf],
                       stdin="".join(f"{s:#x}\n" for s in sites))
            cur = None
            for line in txt.splitlines():
                if re.match(r"^0x[0-9a-f]+$", line):
                    cur = int(line, 16)
                    sources[cur] = []
                elif cur is not None:
                    sources[cur].append(line)
        except (OSError, subprocess.CalledProcessError):
            pass

    reached = len(parent)
    ordered = sorted(calls, key=lambda c: (len(chain(c[0])), c[2]))
    for n, (f, g, site) in enumerate(ordered, 1):
        print(f"panicking call {n}: {names[g]} called at {site:#x} in {names[f]}")
        for k, h in enumerate(chain(f)):
            print(f"    {'  ' * min(k, 1)}{'-> ' if k else ''}{names[h][:160]}")
        print(f"      -> {names[g]}")
        lines = sources.get(site, [])
        if lines:
            print("    call site (innermost first; function, then file:line):")
            for i in range(0, len(lines) - 1, 2):
                fn = short(lines[i])
                print(f"      {lines[i + 1]}  ({fn[:110]})")
    if indirect_seen:
        how = ("followed to every address-taken function" if a.indirect == "address-taken"
               else "NOT followed: the check covers the direct call graph only")
        print(f"panic-check: {len(indirect_seen)} indirect call sites reachable ({how}):")
        for f, s, i in indirect_seen[:40]:
            print(f"    {s:#x} {i} in {names[f][:140]}")
        if len(indirect_seen) > 40:
            print(f"    … and {len(indirect_seen) - 40} more")
    else:
        print("panic-check: no indirect call reachable: the direct call graph is the whole graph")
    print(f"panic-check: {len(calls)} reachable panicking calls from {len(entries)} entry points "
          f"({reached} functions)")
    if calls and os.environ.get("PANIC_CHECK_ALLOW_FAIL") == "1":
        print("panic-check: PANIC_CHECK_ALLOW_FAIL=1: reported only, exit status 0")
        return 0
    return 1 if calls else 0


if __name__ == "__main__":
    sys.exit(main())

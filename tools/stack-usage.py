#!/usr/bin/env python3
"""Static stack use of a Thumb-2 ELF along its call graph.

Usage: tools/stack-usage.py [--exclude XREGEX]... ELF REGEX [REGEX...]

`--exclude XREGEX`: calls into functions matching XREGEX are not followed
(e.g. the out-of-line branches of options that are off by default:
`Filter::second_order_dynamics`, `Filter::update_iterated`); the figure then
bounds the runs that never enter them, and says so.

For every function it reads the whole body in `arm-none-eabi-objdump -d`
and adds up every instruction that moves sp down: `push`, `stmdb sp!`,
`str… [sp, #-n]!`, `vpush`, `vstmdb sp!`, `sub sp, #n` / `sub(w) sp, sp, #n`
(and `add sp, #-n`). The sum bounds the frame on every path through the
function, also when the frame is set up after an early exit (shrink-wrapped
prologues: `Filter::predict` checks its input and returns before it
allocates its frame, so a reader that stops at the first branch sees only
the early path's few bytes). An sp adjustment by a register (a dynamic
allocation) cannot be bounded statically: the function is flagged with `?`.
Code after an early return's `pop` that pushes again is counted twice,
never less than once: the figure is an upper bound of the frame, not an
estimate.

Calls are the direct branches to another function (`bl`, `blx <imm>`,
`b`/`b.w` and the conditional branches: tail calls), by target address,
also into the middle of a function. For each function whose (demangled) name
and address ("name @addr") matches a REGEX it prints its own frame and the
deepest path through the call graph below it (frame sums; a tail call's
frame is added to its caller's, which again only over-counts). The
0xd4d4 halfwords with which lld pads the gap after a function are not
read as branches. Indirect calls are not followed (tools/panic-check.py
lists the indirect calls it meets), and a recursive call is cut where it
re-enters a function already on the path; the output says so and names
where (the firmware's only recursion is in the panic handler's defmt
logging, which the estimator's paths never enter: tools/panic-check.py).
The firmware's stack painting (logged as "peak stack") measures one run
dynamically; this figure bounds it on the direct call graph.
"""
import bisect
import re
import subprocess
import sys

HEAD = re.compile(r"^([0-9a-f]+) <(.*)>:$")
INSN = re.compile(r"^\s*([0-9a-f]+):\t([0-9a-f ]+?)\s*\t(\S+)(?:\t(.*))?$")
# The linker (lld) fills the gap between two functions with 0xd4d4
# halfwords, which disassemble as `bmi.n` into the function before: a run
# of them at the end of a body is padding, not a call.
PADDING = "d4d4"
TARGET = re.compile(r"^([0-9a-f]+) <")
BRANCH = re.compile(r"^(bl|blx|b|cbz|cbnz|b(eq|ne|cs|hs|cc|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le|al))(\.[nw])?$")


def reglist_bytes(args):
    """Bytes stored by a register list `{r4, r5, ..}` / `{d8-d15}`."""
    body = args[args.index("{") + 1:args.index("}")] if "{" in args else ""
    n = 0
    for item in body.split(","):
        item = item.strip()
        if not item:
            continue
        m = re.match(r"([rds])(\d+)-[rds](\d+)$", item)
        size = 8 if item.startswith("d") else 4
        n += (int(m.group(3)) - int(m.group(2)) + 1) * size if m else size
    return n


def sp_down(op, args):
    """Bytes this instruction moves sp down (0 if none); None if unknown."""
    base = op.split(".")[0]
    if base == "push":
        return reglist_bytes(args)
    if base in ("vpush",):
        return reglist_bytes(args)
    if base in ("stmdb", "stmfd", "vstmdb") and args.startswith("sp!"):
        return reglist_bytes(args)
    if base == "str" or base.startswith("str"):
        m = re.search(r"\[sp, #-(\d+)\]!", args)
        return int(m.group(1)) if m else 0
    if base in ("sub", "subw", "subs"):
        m = re.match(r"sp, (?:sp, )?#(\d+)", args)
        if m:
            return int(m.group(1))
        if re.match(r"sp, (?:sp, )?(r\d+|ip|lr)", args):
            return None
        return 0
    if base in ("add", "addw"):
        m = re.match(r"sp, (?:sp, )?#-(\d+)", args)
        return int(m.group(1)) if m else 0
    if base == "mov" and re.match(r"sp, ", args):
        return None
    return 0


def main():
    args, excludes = sys.argv[1:], []
    while len(args) >= 2 and args[0] == "--exclude":
        excludes.append(re.compile(args[1]))
        args = args[2:]
    elf, pats = args[0], [re.compile(p) for p in args[1:]]
    dis = subprocess.run(["arm-none-eabi-objdump", "-d", "-C", elf],
                         capture_output=True, text=True, check=True).stdout
    frames, dynamic, targets, order, start = {}, set(), {}, [], {}
    cur = None
    padding = []  # branch targets of a trailing run of PADDING halfwords
    for line in dis.splitlines():
        m = HEAD.match(line)
        if m:
            padding = []
            cur = m.group(2) + " @" + m.group(1).lstrip("0")
            frames[cur], targets[cur] = 0, set()
            order.append(cur)
            start[cur] = int(m.group(1), 16)
            continue
        if cur is None:
            continue
        m = INSN.match(line)
        if not m:
            continue
        raw, op, args = m.group(2), m.group(3), (m.group(4) or "").strip()
        if op in ("cbz", "cbnz"):
            args = args.split(",", 1)[-1].strip()
        t = TARGET.match(args) if BRANCH.match(op) else None
        if raw == PADDING:
            # Padding if nothing but padding follows it in this body.
            if t:
                padding.append(int(t.group(1), 16))
            continue
        targets[cur].update(padding)
        padding = []
        if BRANCH.match(op):
            if t:
                targets[cur].add(int(t.group(1), 16))
            continue
        d = sp_down(op, args)
        if d is None:
            dynamic.add(cur)
        else:
            frames[cur] += d
    starts = sorted(start[f] for f in order)
    by_addr = {start[f]: f for f in order}

    def owner(addr):
        i = bisect.bisect_right(starts, addr) - 1
        return by_addr[starts[i]] if i >= 0 else None

    calls = {f: {owner(a) for a in ts} - {None, f} for f, ts in targets.items()}
    excluded = {f for f in order if any(x.search(f) for x in excludes)}
    calls = {f: cs - excluded for f, cs in calls.items()}
    memo = {}
    recursive = set()

    # A call back into a function already on the path (recursion) is cut
    # there and reported; a result computed below such a cut depends on the
    # path that led to it, so it is not memoised (a memoised cut result
    # would under-report every later caller).
    def deepest(f, stack=()):
        if f in memo:
            return memo[f]
        if f in stack:
            recursive.add(f)
            return (0, [], True)
        if f not in frames:
            return (0, [], False)
        best = (0, [])
        cut = False
        for c in sorted(calls.get(f, ())):
            d = deepest(c, stack + (f,))
            cut = cut or d[2]
            if d[0] > best[0]:
                best = d[:2]
        r = (frames[f] + best[0], [f] + best[1], cut)
        if not cut:
            memo[f] = r
        return r

    sys.setrecursionlimit(10000)

    def short(s):
        return re.sub(r"::h[0-9a-f]{16}", "", s)

    for f in order:
        if any(p.search(f) for p in pats):
            total, path, cut = deepest(f)
            flag = " (? dynamic sp adjustment on the path: not bounded)" if any(g in dynamic for g in path) else ""
            if cut:
                flag += " (recursion below it, cut at: " + ", ".join(sorted(short(g) for g in recursive)) + ")"
            if excluded:
                flag += " (calls into " + ", ".join(x.pattern for x in excludes) + " not followed)"
            print(f"{short(f)}: own frame {frames[f]} B, deepest call path {total} B{flag}:")
            for g in path:
                print(f"    {frames[g]:>7} B{'?' if g in dynamic else ' '} {short(g)[:120]}")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Static stack use of a Thumb-2 ELF along its call graph.

Usage: tools/stack-usage.py ELF REGEX [REGEX...]

For every function it reads the prologue in `arm-none-eabi-objdump -d`
(push/stmdb/vpush/sub sp until the first branch) to get its frame size, and
collects its direct calls (`bl`/`b.w` to a symbol). For each function whose
(mangled or demangled) name matches a REGEX it prints its own frame and the
deepest path through the call graph below it (frame sums; indirect calls and
recursion are not followed: the firmware has neither on these paths).
The result is an estimate from the binary that runs; the firmware's stack
painting (logged as "peak stack") measures the same run dynamically.
"""
import re
import subprocess
import sys

def main():
    elf, pats = sys.argv[1], [re.compile(p) for p in sys.argv[2:]]
    dis = subprocess.run(["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", "-C", elf],
                         capture_output=True, text=True, check=True).stdout
    frames, calls, order = {}, {}, []
    cur, in_prologue = None, False
    head = re.compile(r"^[0-9a-f]+ <(.*)>:$")
    addr_of = {}
    for line in dis.splitlines():
        m = head.match(line)
        if m:
            cur = m.group(1) + " @" + line.split()[0].lstrip("0")
            frames[cur], calls[cur], in_prologue = 0, set(), True
            order.append(cur)
            continue
        if cur is None or "\t" not in line:
            continue
        parts = line.split("\t")
        if len(parts) < 2:
            continue
        op = parts[1].strip()
        args = parts[2] if len(parts) > 2 else ""
        t = re.search(r"^([0-9a-f]+) <([^>+]+)>", args.strip())
        if t and (op in ("bl", "blx") or op in ("b.w", "b")):
            calls[cur].add(t.group(1).lstrip("0"))
        if not in_prologue:
            continue
        if op.startswith("b") and not op.startswith("bic"):
            in_prologue = False
        elif op == "push" or (op.startswith("stmdb") and args.startswith("sp!")):
            frames[cur] += 4 * len(re.findall(r"[a-z]+[0-9]*", args.split("{")[1]))
        elif op == "vpush":
            regs = args.strip("{} ")
            m2 = re.match(r"([ds])(\d+)-[ds](\d+)", regs)
            if m2:
                n = int(m2.group(3)) - int(m2.group(2)) + 1
            else:
                n = len(regs.split(","))
            frames[cur] += n * (8 if regs.startswith("d") else 4)
        elif op in ("sub", "sub.w", "subw") and args.startswith("sp, sp, #") or op == "sub" and args.startswith("sp, #"):
            frames[cur] += int(re.search(r"#(\d+)", args).group(1))
    by_addr = {f.rsplit(" @", 1)[1]: f for f in order}
    calls = {f: {by_addr[a] for a in cs if a in by_addr and by_addr[a] != f} for f, cs in calls.items()}
    memo = {}
    def deepest(f, stack=()):
        if f in memo:
            return memo[f]
        if f in stack or f not in frames:
            return (0, [])
        best = (0, [])
        for c in calls.get(f, ()):
            d = deepest(c, stack + (f,))
            if d[0] > best[0]:
                best = d
        r = (frames[f] + best[0], [f] + best[1])
        memo[f] = r
        return r
    short = lambda s: re.sub(r"::h[0-9a-f]{16}", "", s)
    for f in order:
        if any(p.search(f) for p in pats):
            total, path = deepest(f)
            print(f"{short(f)}: own frame {frames[f]} B, deepest call path {total} B:")
            for g in path:
                print(f"    {frames[g]:>7} B  {short(g)[:120]}")

if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Prints, for each source tree given, its file count, its largest files and
its longest functions (lines from the `fn` line to its closing brace; test
modules included, comments and blank lines counted).

Usage: python3 tools/code-stats.py [--top N] [DIR ...]   (default: src host-sim/src)

A rough reader of Rust: it counts braces outside strings, chars and
comments, which is enough for rustfmt-formatted code.
"""
import os
import re
import sys

FN = re.compile(r"^\s*(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?(extern\s+\"C\"\s+)?fn\s+(\w+)")


def strip(line, state):
    """The line without strings, chars and comments; state: in block comment."""
    out = []
    i = 0
    n = len(line)
    while i < n:
        if state["block"]:
            j = line.find("*/", i)
            if j < 0:
                return "".join(out)
            state["block"] = False
            i = j + 2
            continue
        c = line[i]
        if line.startswith("//", i):
            break
        if line.startswith("/*", i):
            state["block"] = True
            i += 2
            continue
        if c == '"':
            i += 1
            while i < n and line[i] != '"':
                i += 2 if line[i] == "\\" else 1
            i += 1
            continue
        if c == "'" and i + 2 < n and (line[i + 2] == "'" or (line[i + 1] == "\\" and "'" in line[i + 2 : i + 5])):
            j = line.find("'", i + 2)
            i = j + 1
            continue
        out.append(c)
        i += 1
    return "".join(out)


def functions(path):
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    state = {"block": False}
    code = [strip(l, state) for l in lines]
    found = []
    for k, raw in enumerate(lines):
        m = FN.match(raw)
        if not m:
            continue
        depth = 0
        opened = False
        for j in range(k, len(code)):
            for c in code[j]:
                if c == "{":
                    depth += 1
                    opened = True
                elif c == "}":
                    depth -= 1
                elif c == ";" and not opened and depth == 0:
                    break
            else:
                if opened and depth == 0:
                    found.append((j - k + 1, m.group(7), k + 1))
                    break
                continue
            break
    return found, len(lines)


def main():
    args = sys.argv[1:]
    top = 5
    if args[:1] == ["--top"]:
        top = int(args[1])
        args = args[2:]
    roots = args or ["src", "host-sim/src"]
    for root in roots:
        files = []
        fns = []
        for d, _, names in os.walk(root):
            for name in names:
                if name.endswith(".rs"):
                    p = os.path.join(d, name)
                    f, n = functions(p)
                    files.append((n, p))
                    fns.extend((length, p, line, fname) for length, fname, line in f)
        files.sort(reverse=True)
        fns.sort(reverse=True)
        total = sum(n for n, _ in files)
        print(f"{root}: {len(files)} files, {total} lines")
        print("  largest files:")
        for n, p in files[:top]:
            print(f"    {n:6d}  {p}")
        print("  longest functions:")
        for length, p, line, fname in fns[:top]:
            print(f"    {length:6d}  {fname} ({p}:{line})")
        over = sum(1 for f in fns if f[0] > 100)
        print(f"  functions over 100 lines: {over}")


if __name__ == "__main__":
    main()

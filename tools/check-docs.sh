#!/usr/bin/env bash
# Docs as code: every page's links and commands are checked.
#
#   tools/check-docs.sh [--links-only | --list]
#
# (--list prints the commands of (b) with their page and expected status.)
# (a) Every relative link of README.md, docs/*.md, firmware/README.md,
#     BENCHMARKS.md, CHANGELOG.md and fuzz/README.md resolves: the file
#     exists inside the repository and, for `page.md#anchor`, the page has
#     a heading with that anchor (GitHub's rule). No link may leave the
#     repository or be absolute.
# (b) Every `cargo run …` or `host-sim …` line of the ```sh blocks of
#     README.md and docs/*.md runs from the repository root, page by page
#     in the order written, and exits with status 0, or with the status its
#     comment states (`# exit status 3`). The files a page's commands write
#     (`--out`, `--json`, `--csv`, `--matrices`, …) must exist afterwards;
#     every path a page's commands created is removed after the page.
#     A block opened as ```sh no-run is shown, not run (a study too long
#     for CI): its subcommand's `--help` must list every option it uses.
# (c) `host-sim SUB --help` succeeds for every subcommand SUB named
#     anywhere in those pages.
#
# Needs a release build of host-sim (`cargo build --release -p host-sim`)
# for (c) and the no-run checks; the commands of (b) build what they need.
# Prints the wall time of each page. Run from anywhere.
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."
ROOT=$(pwd)
HOST_SIM="$ROOT/target/release/host-sim"
LINK_PAGES=(README.md docs/*.md firmware/README.md BENCHMARKS.md CHANGELOG.md fuzz/README.md)
RUN_PAGES=(README.md docs/*.md)
START=$SECONDS

fail() {
    echo "FAIL: $*" >&2
    exit 1
}

# ---------------------------------------------------------------- (a) links
echo "==> links of ${LINK_PAGES[*]}"
python3 - "${LINK_PAGES[@]}" <<'PY'
import os, re, sys

root = os.getcwd()

def strip_code(text):
    """Text without fenced blocks and inline code spans (links there are not links)."""
    out, fence = [], None
    for line in text.split('\n'):
        m = re.match(r'^\s*(`{3,}|~{3,})', line)
        if m:
            mark = m.group(1)
            if fence is None:
                fence = mark
            elif mark.startswith(fence[0]) and len(mark) >= len(fence):
                fence = None
            out.append('')
            continue
        out.append('' if fence else re.sub(r'`+[^`]*`+', '', line))
    return '\n'.join(out)

def slug(heading):
    h = re.sub(r'`', '', heading.strip()).lower()
    h = re.sub(r'\[([^\]]*)\]\([^)]*\)', r'\1', h)
    h = ''.join(c for c in h if c.isalnum() or c in ' -_')
    return h.replace(' ', '-')

anchor_cache = {}

def anchors(path):
    if path not in anchor_cache:
        seen, result = {}, set()
        fence = None
        for line in open(path, encoding='utf-8').read().split('\n'):
            m = re.match(r'^\s*(`{3,}|~{3,})', line)
            if m:
                fence = None if fence else m.group(1)
                continue
            if fence:
                continue
            m = re.match(r'^#{1,6}\s+(.*?)\s*#*\s*$', line)
            if m:
                s = slug(m.group(1))
                n = seen.get(s, 0)
                seen[s] = n + 1
                result.add(s if n == 0 else f'{s}-{n}')
        anchor_cache[path] = result
    return anchor_cache[path]

errors = 0
count = 0
for page in sys.argv[1:]:
    text = strip_code(open(page, encoding='utf-8').read())
    links = re.findall(r'!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+"[^"]*")?\s*\)', text)
    links += re.findall(r'^\s*\[[^\]]+\]:\s*(\S+)', text, re.M)
    for link in links:
        if re.match(r'^[a-z][a-z0-9+.-]*:', link, re.I):
            continue  # http:, https:, mailto: … (outside the file tree by nature)
        count += 1
        where = f'{page}: ({link})'
        target, _, anchor = link.partition('#')
        if target.startswith('/'):
            print(f'FAIL: {where}: absolute path'); errors += 1; continue
        path = os.path.normpath(os.path.join(os.path.dirname(page), target)) if target else page
        if os.path.relpath(os.path.abspath(path), root).startswith('..'):
            print(f'FAIL: {where}: points outside the repository'); errors += 1; continue
        if not os.path.exists(path):
            print(f'FAIL: {where}: no such file {path}'); errors += 1; continue
        if anchor and path.endswith('.md') and anchor not in anchors(path):
            print(f'FAIL: {where}: no heading #{anchor} in {path}'); errors += 1
print(f'checked {count} relative links')
sys.exit(1 if errors else 0)
PY

if [ "${1:-}" = "--links-only" ]; then
    exit 0
fi

# ------------------------------------------------- (b) the pages' commands
# One record per command: page, kind (run|show), expected exit status, line.
extract_commands() {
    awk -v page="$1" '
        /^```/ {
            if (!blk) {
                blk = 1
                info = substr($0, 4)
                sh = (info ~ /^sh([ ,]|$)/)
                show = (info ~ /no-run/)
            } else {
                blk = 0; sh = 0
            }
            next
        }
        blk && sh {
            line = $0
            while (line ~ /\\$/ && (getline nxt) > 0) {
                sub(/\\$/, "", line); line = line nxt
            }
            if (line ~ /^(cargo run |host-sim )/) {
                status = 0
                if (match(line, /# exit status [0-9]+/)) {
                    status = substr(line, RSTART + 14, RLENGTH - 14) + 0
                }
                printf "%s\t%s\t%d\t%s\n", page, (show ? "show" : "run"), status, line
            }
        }' "$1"
}

# The host-sim subcommand of a command line, if any.
subcommand_of() {
    sed -nE 's/.*(-p host-sim( -[-a-z]+)* --|^host-sim) ([a-z][a-z-]*).*/\3/p' <<<"$1" | head -1
}

if [ "${1:-}" = "--list" ]; then
    for page in "${RUN_PAGES[@]}"; do extract_commands "$page"; done
    exit 0
fi
[ -x "$HOST_SIM" ] || fail "no $HOST_SIM: run 'cargo build --release -p host-sim' first"

snapshot() {
    find . \( -path ./.git -o -path ./target -o -path ./firmware/target -o -path ./fuzz/target \
        -o -path ./fuzz/corpus -o -path ./fuzz/artifacts \) -prune -o -print | LC_ALL=C sort
}

LOG=$(mktemp)
trap 'rm -f "$LOG"' EXIT
export PATH="$ROOT/target/release:$PATH"
RAN=0
SHOWN=0
for page in "${RUN_PAGES[@]}"; do
    COMMANDS=$(extract_commands "$page")
    [ -n "$COMMANDS" ] || continue
    PAGE_START=$SECONDS
    echo "==> commands of $page"
    BEFORE=$(snapshot)
    DIFF_BEFORE=$(git diff 2>/dev/null | sha1sum)
    while IFS=$'\t' read -r _ kind want cmd; do
        if [ "$kind" = show ]; then
            sub=$(subcommand_of "$cmd")
            printf '  (shown, not run) %s\n' "$cmd"
            if [ -n "$sub" ]; then
                help=$("$HOST_SIM" "$sub" --help) || fail "$page: 'host-sim $sub --help' failed (for: $cmd)"
            else
                help=""
            fi
            for opt in $(grep -oE -- ' --[a-z][a-z0-9-]*' <<<"${cmd%%#*}" | sort -u); do
                case "$opt" in
                --release | --locked | --manifest-path | --bin | --package) continue ;;
                esac
                if [ -n "$sub" ] && ! grep -qE -- "$opt([ ,=]|$)" <<<"$help"; then
                    fail "$page: 'host-sim $sub --help' has no option $opt (for: $cmd)"
                fi
            done
            SHOWN=$((SHOWN + 1))
            continue
        fi
        printf '+ %s\n' "$cmd"
        set +e
        (cd "$ROOT" && bash -o pipefail -c "$cmd") >"$LOG" 2>&1 </dev/null
        got=$?
        set -e
        if [ "$got" != "$want" ]; then
            tail -n 30 "$LOG" >&2
            fail "$page: exit status $got, the page says $want: $cmd"
        fi
        for f in $(grep -oE -- '--(out|json|csv|matrices|matrices-txt|report|truth|figure) [^ ]+' <<<"${cmd%%#*}" | awk '{print $2}'); do
            [ "$f" = - ] && continue
            [ -e "$f" ] && { [ -d "$f" ] || [ -s "$f" ]; } || fail "$page: '$cmd' wrote no $f"
        done
        RAN=$((RAN + 1))
    done <<<"$COMMANDS"
    # Remove what the page's commands created (outermost new paths only).
    comm -13 <(echo "$BEFORE") <(snapshot) | awk '
        { for (i = 0; i < n; i++) if (index($0, kept[i] "/") == 1) next; kept[n++] = $0; print }' |
        while IFS= read -r path; do rm -rf -- "$path"; done
    [ "$(git diff 2>/dev/null | sha1sum)" = "$DIFF_BEFORE" ] || fail "$page: a command modified a tracked file (git diff)"
    printf '    (%s: %d s)\n' "$page" $((SECONDS - PAGE_START))
done
echo "ran $RAN commands, checked the options of $SHOWN shown ones"

# ------------------------------------------- (c) --help of every subcommand
echo "==> host-sim --help of every subcommand the pages name"
SUBCOMMANDS=$(
    {
        grep -ohE -- '-p host-sim( -[-a-z]+)* -- [a-z][a-z-]*' "${LINK_PAGES[@]}" | awk '{print $NF}' || true
        grep -ohE -- '`host-sim [a-z][a-z-]*' "${LINK_PAGES[@]}" | awk '{print $2}' || true
        grep -ohE -- '^host-sim [a-z][a-z-]*' "${LINK_PAGES[@]}" | awk '{print $2}' || true
    } | LC_ALL=C sort -u
)
"$HOST_SIM" --help >/dev/null || fail "'host-sim --help' failed"
for sub in $SUBCOMMANDS; do
    "$HOST_SIM" "$sub" --help >/dev/null 2>&1 ||
        fail "'host-sim $sub --help' failed: a page names a subcommand that does not exist"
done
echo "checked: $(echo $SUBCOMMANDS)"
echo "check-docs: all passed in $((SECONDS - START)) s"

#!/usr/bin/env bash
# tools/check-report.sh DIR [SCREENSHOT.png]
#
# Renders DIR/index.html (written by `host-sim run|calibrate --report DIR`)
# in headless Chromium (Debian's `chromium`, installed with apt-get if
# missing) and fails unless the page's own check script reported
# data-report-check="ok": every figure loaded (complete, naturalWidth > 0),
# the expected number of figures present, no script error. With
# SCREENSHOT.png, also writes a screenshot of the top of the page (1280 px
# wide, $CHECK_REPORT_HEIGHT px high, default 2400).
#
# Self-test (proves the check can fail): tools/check-report.sh --self-test DIR
# copies DIR, deletes one figure of the copy and expects the check to fail,
# then breaks the page's script and expects that to fail too.
set -euo pipefail

die() { echo "check-report: $*" >&2; exit 1; }

ensure_chromium() {
    if ! command -v chromium >/dev/null; then
        local sudo=()
        [ "$(id -u)" -eq 0 ] || sudo=(sudo)
        echo "check-report: installing chromium" >&2
        "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends chromium fonts-dejavu-core >/dev/null ||
            { "${sudo[@]}" apt-get update >/dev/null &&
                "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends chromium fonts-dejavu-core >/dev/null; }
    fi
    command -v chromium >/dev/null || die "chromium is not installed and could not be installed"
}

# Chromium with a throw-away profile; no network is needed (file:// only).
browser() {
    local profile
    profile=$(mktemp -d)
    # Chromium's stderr is noise (dbus, GPU) unless it fails.
    local log
    log=$(mktemp)
    if ! timeout 120 chromium --headless --no-sandbox --disable-gpu --no-first-run \
        --disable-extensions --user-data-dir="$profile" --virtual-time-budget=5000 \
        "$@" 2>"$log"; then
        cat "$log" >&2
        rm -rf "$profile" "$log"
        return 1
    fi
    rm -rf "$profile" "$log"
}

# check DIR: prints the page's data-report-check and fails unless "ok".
check() {
    local dir=$1 page state
    page="$(cd "$dir" && pwd)/index.html"
    [ -f "$page" ] || die "no $page"
    local dom
    dom=$(browser --dump-dom "file://$page") || die "chromium failed on $page"
    state=$(printf '%s' "$dom" | grep -o 'data-report-check="[^"]*"' | head -n 1 || true)
    [ -n "$state" ] || die "$page: no data-report-check attribute in the rendered page"
    echo "check-report: $page: $state"
    [ "$state" = 'data-report-check="ok"' ]
}

ensure_chromium

if [ "${1:-}" = "--self-test" ]; then
    [ $# -eq 2 ] || die "usage: $0 --self-test DIR"
    check "$2" || die "self-test: the original report does not pass"
    tmp=$(mktemp -d)
    trap 'rm -rf "$tmp"' EXIT
    cp -r "$2" "$tmp/missing"
    fig=$(find "$tmp/missing" -name '*.png' | sort | head -n 1)
    [ -n "$fig" ] || die "self-test: $2 has no figure to delete"
    rm "$fig"
    if check "$tmp/missing"; then
        die "self-test: the check passed with $(basename "$fig") deleted"
    fi
    cp -r "$2" "$tmp/script"
    sed -i 's|</body>|<script>undefinedFunction();</script></body>|' "$tmp/script/index.html"
    if check "$tmp/script"; then
        die "self-test: the check passed with a script error"
    fi
    echo "check-report: self-test passed (a missing figure and a script error both fail the check)"
    exit 0
fi

[ $# -ge 1 ] && [ $# -le 2 ] || die "usage: $0 DIR [SCREENSHOT.png] | --self-test DIR"
check "$1" || die "the report in $1 failed the browser check"
if [ $# -eq 2 ]; then
    shot=$(cd "$(dirname "$2")" && pwd)/$(basename "$2")
    page="$(cd "$1" && pwd)/index.html"
    browser --hide-scrollbars --window-size="1280,${CHECK_REPORT_HEIGHT:-2400}" --screenshot="$shot" "file://$page" ||
        die "chromium could not write the screenshot $shot"
    [ -s "$shot" ] || die "no screenshot written to $shot"
    echo "check-report: screenshot $shot"
fi

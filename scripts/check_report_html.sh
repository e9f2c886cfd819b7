#!/usr/bin/env bash
# Open a report.html in headless Chromium and check that every image on it loads.
#
#   scripts/check_report_html.sh RESULT_DIR [--install] [--screenshot FILE.png]
#
# Loads RESULT_DIR/report.html from disk (file://) with a script injected into a copy of
# the page (in the same folder, removed afterwards) that, once the page has loaded, counts
# the <img> elements and those that decoded (complete && naturalWidth > 0) and writes the
# counts into a data attribute; --dump-dom prints the DOM, from which the counts are read.
# Prints "images: LOADED/TOTAL" and exits 0 only when TOTAL > 0 and every image loaded;
# 1 when one did not (the failing sources are listed); 2 when Chromium is missing (with
# --install it is installed from Debian's packages first: apt-get install -y chromium).
set -euo pipefail
dir="${1:?usage: $0 RESULT_DIR [--install] [--screenshot FILE.png]}"
shift
install=0
shot=""
while [ $# -gt 0 ]; do
    case "$1" in
        --install) install=1 ;;
        --screenshot) shot="$2"; shift ;;
        *) echo "unknown option $1" >&2; exit 2 ;;
    esac
    shift
done
page="$dir/report.html"
[ -f "$page" ] || { echo "check_report_html: no $page" >&2; exit 2; }
chrome=""
for c in chromium chromium-browser google-chrome; do
    if command -v "$c" >/dev/null; then chrome="$(command -v "$c")"; break; fi
done
if [ -z "$chrome" ] && [ "$install" = 1 ]; then
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium >/dev/null
    chrome="$(command -v chromium || true)"
fi
[ -n "$chrome" ] || { echo "check_report_html: chromium not found (pass --install, or apt-get install chromium)" >&2; exit 2; }

profile="$(mktemp -d)"
probe="$dir/.report.check.html"
trap 'rm -rf "$profile" "$probe"' EXIT
# The probe script runs after every image has loaded or failed (window load event).
sed 's#</body>#<script>window.addEventListener("load",function(){var i=document.images,ok=0,bad=[];for(var k=0;k<i.length;k++){if(i[k].complete\&\&i[k].naturalWidth>0){ok++}else{bad.push(i[k].getAttribute("src"))}}document.body.setAttribute("data-images",ok+"/"+i.length);document.body.setAttribute("data-failed",bad.join(" "));});</script></body>#' "$page" > "$probe"
flags=(--headless --no-sandbox --disable-gpu --disable-quic --no-first-run
       --disable-background-networking --disable-component-update --disable-sync
       --allow-file-access-from-files --user-data-dir="$profile" --virtual-time-budget=10000)
url="file://$(cd "$(dirname "$probe")" && pwd)/$(basename "$probe")"
dom="$(timeout 120 "$chrome" "${flags[@]}" --dump-dom "$url" 2>/dev/null)"
counts="$(printf '%s' "$dom" | grep -o 'data-images="[0-9]*/[0-9]*"' | head -1 | grep -o '[0-9]*/[0-9]*' || true)"
failed="$(printf '%s' "$dom" | grep -o 'data-failed="[^"]*"' | head -1 | sed 's/data-failed="//; s/"$//' || true)"
if [ -n "$shot" ]; then
    timeout 120 "$chrome" "${flags[@]}" --window-size=1280,4000 --screenshot="$shot" "$url" >/dev/null 2>&1 || true
fi
if [ -z "$counts" ]; then
    echo "check_report_html: the page did not finish loading in Chromium" >&2
    exit 1
fi
echo "images: $counts"
loaded="${counts%/*}"
total="${counts#*/}"
if [ "$total" -eq 0 ] || [ "$loaded" -ne "$total" ]; then
    [ -n "$failed" ] && echo "not loaded: $failed"
    exit 1
fi

#!/usr/bin/env bash
# Renders a polycal HTML report with headless Chromium: a PNG of its first screen (for the
# README's picture and for anyone checking the look) and, optionally, the A4 PDF a browser
# prints. Chromium is not needed by polycal itself, nor by its tests or CI.
#
#   scripts/render-report.sh REPORT.html OUT.png [OUT.pdf] [WIDTHxHEIGHT]
#
# Chromium: Debian's package `chromium` (/usr/bin/chromium); set CHROMIUM to use another.
# Runs with no network access of its own (the report fetches nothing).
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: $0 REPORT.html OUT.png [OUT.pdf] [WIDTHxHEIGHT]" >&2
  exit 2
fi
report=$1
png=$2
pdf=${3:-}
size=${4:-1000x1400}
browser=${CHROMIUM:-$(command -v chromium || command -v chromium-browser || command -v google-chrome || true)}
if [ -z "$browser" ]; then
  echo "error: no Chromium found (install Debian's package chromium, or set CHROMIUM)" >&2
  exit 2
fi
if [ ! -f "$report" ]; then
  echo "error: $report: no such file" >&2
  exit 2
fi
url="file://$(cd "$(dirname "$report")" && pwd)/$(basename "$report")"
profile=$(mktemp -d)
trap 'rm -rf "$profile"' EXIT
flags=(--headless --no-sandbox --disable-gpu --disable-quic --no-first-run
  --disable-background-networking --disable-component-update --disable-sync
  --hide-scrollbars --user-data-dir="$profile")
"$browser" "${flags[@]}" --window-size="${size/x/,}" --screenshot="$png" "$url" 2>/dev/null
echo "wrote $png"
if [ -n "$pdf" ]; then
  "$browser" "${flags[@]}" --no-pdf-header-footer --print-to-pdf="$pdf" "$url" 2>/dev/null
  echo "wrote $pdf"
fi

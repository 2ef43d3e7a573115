#!/usr/bin/env bash
# Opens report.html of the two bundled samples in headless Chromium: fails on
# any console message (script errors, resources that failed to load), on
# external URLs, or when the page does not render; keeps the screenshots in
# OUTDIR for a person to look at. The embedded WebGL viewer must draw (software
# WebGL through ANGLE's SwiftShader, flags below) and, with WebGL turned off,
# show its fallback message, both without console messages. Then checks that a
# machine without any X display or Xvfb still gets a complete report that says
# why it has no 3D views.
set -euo pipefail
BIN=$1 SRC=$2 OUT=$3
command -v chromium >/dev/null || { echo "FAIL: chromium is not installed (scripts/install-deps installs it)"; exit 1; }
rm -rf "$OUT" && mkdir -p "$OUT"
for sample in symmetric ramus_L_plus4mm; do
  "$BIN" run "$SRC/sample_dicom/$sample/dicom" -o "$OUT/$sample" -q
  html="$OUT/$sample/report.html"
  grep -q 'view_mirror_front' "$html" || { echo "FAIL: $sample: no 3D views in the report"; exit 1; }
  if grep -Eq '(src|href)="(https?:)?//' "$html"; then echo "FAIL: $sample: the report loads external URLs"; exit 1; fi
  grep -q 'id="ms-viewer"' "$html" || { echo "FAIL: $sample: no interactive viewer in the report"; exit 1; }
  grep -q 'data-band="' "$html" || { echo "FAIL: $sample: no interpretation bands in the headline"; exit 1; }
  log="$OUT/$sample.chromium.log"
  # Software WebGL: without --enable-unsafe-swiftshader Chromium falls back with
  # a deprecation message on the console; the ANGLE backend is the quiet one.
  gl=(--use-angle=swiftshader --enable-unsafe-swiftshader)
  timeout 120 chromium --headless=new --no-sandbox "${gl[@]}" --hide-scrollbars --window-size=1200,2600 \
    --enable-logging=stderr --v=0 --screenshot="$OUT/report_$sample.png" "file://$html" > "$log" 2>&1 || true
  if grep -q ':CONSOLE' "$log"; then echo "FAIL: $sample: console messages:"; grep ':CONSOLE' "$log"; exit 1; fi
  size=$(stat -c %s "$OUT/report_$sample.png" 2>/dev/null || echo 0)
  [ "$size" -gt 50000 ] || { echo "FAIL: $sample: screenshot missing or blank ($size bytes)"; exit 1; }
  echo "ok: $sample: screenshot $OUT/report_$sample.png ($size bytes; headline, bands and the viewer)"
  # The DOM after the scripts ran: the viewer marks itself drawn.
  timeout 120 chromium --headless=new --no-sandbox "${gl[@]}" --window-size=1200,2600 --enable-logging=stderr --v=0 \
    --dump-dom "file://$html" > "$OUT/$sample.dom.html" 2> "$log.dom" || true
  if grep -q ':CONSOLE' "$log.dom"; then echo "FAIL: $sample: console messages (dump-dom):"; grep ':CONSOLE' "$log.dom"; exit 1; fi
  grep -q 'data-viewer="drawn"' "$OUT/$sample.dom.html" ||
    { echo "FAIL: $sample: the viewer did not draw ($(grep -o 'data-viewer="[a-z-]*"' "$OUT/$sample.dom.html"))"; exit 1; }
  echo "ok: $sample: the interactive viewer drew with software WebGL"
done
# WebGL off: the viewer says so instead of drawing, and the page stays clean.
html="$OUT/ramus_L_plus4mm/report.html" log="$OUT/nowebgl.chromium.log"
timeout 120 chromium --headless=new --no-sandbox --disable-gpu --disable-webgl --hide-scrollbars --window-size=1200,2600 \
  --enable-logging=stderr --v=0 --screenshot="$OUT/report_nowebgl.png" "file://$html" > "$log" 2>&1 || true
timeout 120 chromium --headless=new --no-sandbox --disable-gpu --disable-webgl --enable-logging=stderr --v=0 \
  --dump-dom "file://$html" > "$OUT/nowebgl.dom.html" 2>> "$log" || true
if grep -q ':CONSOLE' "$log"; then echo "FAIL: WebGL off: console messages:"; grep ':CONSOLE' "$log"; exit 1; fi
grep -q 'data-viewer="no-webgl"' "$OUT/nowebgl.dom.html" || { echo "FAIL: WebGL off: no fallback state"; exit 1; }
grep -q 'class="viewer-status warn">Interactive 3D view unavailable' "$OUT/nowebgl.dom.html" || { echo "FAIL: WebGL off: no fallback message"; exit 1; }
echo "ok: with WebGL off the viewer shows its message (screenshot $OUT/report_nowebgl.png)"
# No display, no Xvfb on PATH: the run still succeeds, without views, and says why.
empty=$(mktemp -d)
env -u DISPLAY PATH="$empty" "$BIN" run "$SRC/sample_dicom/symmetric/dicom" -o "$OUT/nodisplay" -q
grep -q '3D views not rendered' "$OUT/nodisplay/report.html" || { echo "FAIL: no-display report does not say why"; exit 1; }
grep -q 'Xvfb is not installed' "$OUT/nodisplay/results.json" || { echo "FAIL: no-display warning missing"; exit 1; }
[ ! -e "$OUT/nodisplay/qc/view_mirror_front.png" ] || { echo "FAIL: views written without a display"; exit 1; }
echo "ok: without a display the report is complete and says why it has no 3D views"

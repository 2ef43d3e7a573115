#!/usr/bin/env bash
# Runs workflow/Snakefile locally (--cores 2) on three generated phantoms plus
# one folder that is not a scan; checks the cohort files.
set -euo pipefail
BIN=$1 SRC=$2 WORK=$3
command -v snakemake >/dev/null || { echo "FAIL: snakemake is not installed (scripts/install-deps installs it)"; exit 1; }
rm -rf "$WORK" && mkdir -p "$WORK/studies"
"$BIN" phantom -o "$WORK/gen/sym" --spacing 1 --fov 140,120,120 --no-preview > /dev/null
"$BIN" phantom -o "$WORK/gen/ramus" --spacing 1 --fov 140,120,120 --ramus-L 4 --no-preview > /dev/null
"$BIN" phantom -o "$WORK/gen/posed" --spacing 1 --fov 140,120,120 --yaw 10 --no-preview > /dev/null
for s in sym ramus posed; do ln -s "$WORK/gen/$s/dicom" "$WORK/studies/$s"; done
mkdir "$WORK/studies/empty"
snakemake -s "$SRC/workflow/Snakefile" --profile "$SRC/workflow/profiles/local" --cores 2 -d "$WORK" \
  --config source="$WORK/studies" out="$WORK/out" mandisym="$BIN" > "$WORK/snakemake.log" 2>&1 || { cat "$WORK/snakemake.log"; exit 1; }
csv="$WORK/out/cohort.csv"
for s in sym ramus posed; do grep -q "^\"$s\",\"done-earlier\",0," "$csv" || { echo "FAIL: $s not complete"; cat "$csv"; exit 1; }; done
grep -q '^"empty","failed",4,' "$csv" || { echo "FAIL: the empty study is not listed as failed with its exit code 4"; cat "$csv"; exit 1; }
grep -Eq '^0 [0-9]+$' "$WORK/out/.done/sym" || { echo "FAIL: .done/sym does not hold 'EXIT SECONDS'"; cat "$WORK/out/.done/sym"; exit 1; }
grep -q 'href="sym/report.html"' "$WORK/out/cohort.html" || { echo "FAIL: cohort.html has no link"; exit 1; }
echo "ok: snakemake workflow: 3 studies complete, 1 failed and listed"

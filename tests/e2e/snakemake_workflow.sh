#!/usr/bin/env bash
# Runs workflow/Snakefile locally (--cores 2) on a CSV cohort: three generated
# phantoms (one with its own hu_offset, one with its own mask and label) and one
# folder that is not a scan, with run_args for every study. Checks the cohort
# files, the options each run was given, that the failed study is not taken for
# done, that batch and Snakemake skip each other's done studies (with identical
# numbers), and that `snakemake --lint` finds nothing.
set -euo pipefail
BIN=$1 SRC=$2 WORK=$3
fail() { echo "FAIL: $*"; exit 1; }
command -v snakemake >/dev/null || fail "snakemake is not installed (scripts/install-deps installs it)"
rm -rf "$WORK" && mkdir -p "$WORK/studies/empty"
"$BIN" phantom -o "$WORK/gen/sym" --spacing 1 --fov 140,120,120 --no-preview > /dev/null
"$BIN" phantom -o "$WORK/gen/ramus" --spacing 1 --fov 140,120,120 --ramus-L 4 --no-preview > /dev/null
"$BIN" phantom -o "$WORK/gen/posed" --spacing 1 --fov 140,120,120 --yaw 10 --no-preview > /dev/null
cat > "$WORK/studies.csv" <<'EOF'
id,path,hu_offset,mask,label
sym,gen/sym/dicom,,,
ramus,gen/ramus/dicom,10,,
posed,gen/posed/dicom,,gen/posed/ground_truth/mandible_mask.nii.gz,1
empty,studies/empty,,,
EOF
out="$WORK/out" csv="$WORK/out/cohort.csv"
sm() {
  snakemake -s "$SRC/workflow/Snakefile" --profile "$SRC/workflow/profiles/local" --cores 2 -d "$WORK" \
    --config source="$WORK/studies.csv" out="$out" mandisym="$BIN" run_args="--bone-threshold 260" "$@"
}
planned() {  # the studies a dry run would run, one line
  sm -n 2>&1 | sed -n 's/^ *wildcards: sid=//p' | sort | tr '\n' ' '
}

rc=0
sm > "$WORK/snakemake.log" 2>&1 || rc=$?
[ "$rc" -eq 1 ] || { cat "$WORK/snakemake.log"; fail "snakemake exited $rc, expected 1 (a study failed)"; }
for s in sym ramus posed; do grep -q "^\"$s\",\"done-earlier\",0," "$csv" || { cat "$csv"; fail "$s not complete"; }; done
grep -q '^"empty","failed",4,' "$csv" || { cat "$csv"; fail "the empty study is not listed as failed with its exit code 4"; }
grep -Eq '^0 [0-9.]+$' "$out/.done/sym" || { cat "$out/.done/sym"; fail ".done/sym does not hold 'EXIT SECONDS'"; }
grep -q 'href="sym/report.html"' "$out/cohort.html" || fail "cohort.html has no link"

# run_args for all; the CSV's hu_offset, mask and label (relative to the CSV) for their study.
python3 - "$out" <<'EOF' || fail "a study's run did not get its options"
import json, sys
r = {s: json.load(open(f"{sys.argv[1]}/{s}/results.json")) for s in ("sym", "ramus", "posed")}
assert all(d["parameters"]["bone_threshold_hu"] == 260 for d in r.values()), "run_args"
assert r["sym"]["parameters"]["hu_offset"] == 0 and r["ramus"]["parameters"]["hu_offset"] == 10, "hu_offset"
assert r["posed"]["segmentation"]["method"] == "external" and r["sym"]["segmentation"]["method"] == "auto", "mask"
EOF

# The failed study is not done: a dry run plans it again, and only it.
[ "$(planned)" = "empty " ] || fail "a dry run plans '$(planned)', expected only 'empty'"

# batch skips Snakemake's done studies and runs the others with the same options
# and numbers; Snakemake then skips the study batch ran.
cp "$out/posed/results.json" "$WORK/posed.snakemake.json"
rm -rf "$out/posed"
rc=0
"$BIN" batch "$WORK/studies.csv" -o "$out" -q -- --bone-threshold 260 || rc=$?
[ "$rc" -eq 9 ] || fail "batch exited $rc, expected 9 (the empty study)"
for s in sym ramus; do grep -q "^\"$s\",\"done-earlier\"," "$csv" || { cat "$csv"; fail "batch re-ran $s"; }; done
grep -q '^"posed","ok",0,.*--bone-threshold 260 --mask [^,]*gen/posed/ground_truth/mandible_mask.nii.gz --label 1"' "$csv" ||
  { cat "$csv"; fail "batch did not run posed with run_args and its own options"; }
python3 - "$WORK/posed.snakemake.json" "$out/posed/results.json" <<'EOF' || fail "batch and Snakemake give different numbers for posed"
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:])
for k in ("scores", "parameters", "landmarks", "symmetry_plane"):
    assert a[k] == b[k], k
EOF
[ "$(planned)" = "empty " ] || fail "after batch a dry run plans '$(planned)', expected only 'empty'"

# A bad per-study value stops the workflow before any job is planned or submitted.
sed 's/^ramus,gen\/ramus\/dicom,10,,/ramus,gen\/ramus\/dicom,ten,,/' "$WORK/studies.csv" > "$WORK/bad.csv"
rc=0
bad=$(snakemake -s "$SRC/workflow/Snakefile" --profile "$SRC/workflow/profiles/local" --cores 2 -d "$WORK" \
  --config source="$WORK/bad.csv" out="$WORK/out-bad" mandisym="$BIN" 2>&1) || rc=$?
[ "$rc" -ne 0 ] && grep -q "run options refused.*hu-offset" <<<"$bad" || { echo "$bad"; fail "a bad hu_offset was not refused"; }
[ ! -e "$WORK/out-bad/sym" ] || fail "a study ran although the options were refused"

lint=$(sm --lint 2>&1) || true
grep -q "Lints for" <<<"$lint" && { echo "$lint"; fail "snakemake --lint"; }
echo "ok: snakemake workflow: 3 studies complete with their options, 1 failed, listed and planned again; batch and Snakemake skip each other's; bad options refused before any job; no lints"

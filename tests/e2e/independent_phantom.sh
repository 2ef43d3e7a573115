#!/usr/bin/env bash
# A phantom of another design (scripts/phantom-independent, docs/phantom-independent.md: written
# from anthropometry without reading the project's own phantom): the mouth-open case at 1 mm runs
# through scripts/validate-independent-phantoms. The pipeline was never tuned on it; it must give
# exit 0, QC pass, all 8 landmarks within 2 mm of the design's, and Dice >= 0.95 against the design's
# mask (measured: landmarks <= 1.2 mm, Dice 0.984). Closed-mouth cases are not held here: they fail
# QC today (docs/phantom-independent.md, "Results").
set -euo pipefail
BIN=$1 SRC=$2 WORK=$3
fail() { echo "FAIL: $*"; exit 1; }
/usr/bin/python3 -c "import numpy, scipy, nibabel" 2>/dev/null || fail "python3-numpy, python3-scipy and python3-nibabel are needed (scripts/install-deps)"
rm -rf "$WORK"
"$SRC/scripts/validate-independent-phantoms" -o "$WORK" --bin "$BIN" --cases open15 --jobs 1 --gen-jobs 1
/usr/bin/python3 - "$WORK/per_case.csv" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
assert len(rows) == 1 and rows[0]["case"] == "open15", rows
r = rows[0]
bad = []
if r["exit"] != "0": bad.append(f"exit {r['exit']}")
if r["qc_status"] != "pass": bad.append(f"qc {r['qc_status']}")
for l in ["Co_L", "Co_R", "Cr_L", "Cr_R", "Go_L", "Go_R", "Me", "Pog"]:
    v = r[f"{l}_err_mm"]
    if v in ("", "missing") or float(v) > 2.0: bad.append(f"{l} {v or 'missing'}")
if float(r["dice"] or 0) < 0.95: bad.append(f"Dice {r['dice']}")
print("open15:", ", ".join(f"{l} {r[l + '_err_mm']}" for l in ["Co_L", "Co_R", "Cr_L", "Cr_R", "Go_L", "Go_R", "Me", "Pog"]), "Dice", r["dice"])
if bad:
    print("FAIL: " + "; ".join(bad)); sys.exit(1)
PY
rm -rf "$WORK"

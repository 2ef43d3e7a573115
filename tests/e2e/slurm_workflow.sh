#!/usr/bin/env bash
# Runs workflow/Snakefile with workflow/profiles/slurm through a real
# single-node Slurm (scripts/slurm-local: munged, slurmctld, slurmd of Debian's
# slurm-wlm) on three studies, one of them corrupt (a DICOM series cut short).
# Checks: every study was an sbatch job (Slurm's jobcomp records); the corrupt
# one failed, was retried once (restart-times 1) and is listed as failed with
# its real exit code in complete cohort files; once repaired, a second run
# submits only it and then the cohort job; the daemons are stopped afterwards.
set -euo pipefail
BIN=$1 SRC=$2 WORK=$3
fail() { echo "FAIL: $*"; exit 1; }
for b in snakemake munged slurmctld slurmd sbatch scontrol; do
  command -v "$b" >/dev/null || fail "$b is not installed (scripts/install-deps installs snakemake, slurmctld, slurmd, slurm-client and munge)"
done
rm -rf "$WORK" && mkdir -p "$WORK/studies"
"$BIN" phantom -o "$WORK/gen/sym" --spacing 1 --fov 140,120,120 --no-preview > /dev/null
"$BIN" phantom -o "$WORK/gen/ramus" --spacing 1 --fov 140,120,120 --ramus-L 4 --no-preview > /dev/null
for s in sym ramus; do ln -s "$WORK/gen/$s/dicom" "$WORK/studies/$s"; done
cp -r "$WORK/gen/sym/dicom" "$WORK/studies/corrupt"
for f in "$WORK/studies/corrupt"/*; do truncate -s 600 "$f"; done

STATE=
stop_slurm() {
  [ -z "$STATE" ] || "$SRC/scripts/slurm-local" stop "$STATE" || true
}
trap stop_slurm EXIT
STATE=$("$SRC/scripts/slurm-local" start)
export SLURM_CONF="$STATE/slurm.conf"
export CI=true  # Snakemake polls every 1 s instead of 10 s
sm() {  # the profile as documented; only latency-wait shorter (one machine, no NFS)
  # Each run within 120 s, so that a hang ends here (and the trap stops the
  # daemons) before ctest's 300 s limit kills this script.
  timeout -k 5 120 snakemake -s "$SRC/workflow/Snakefile" --profile "$SRC/workflow/profiles/slurm" --latency-wait 5 -d "$WORK" \
    --config source="$WORK/studies" out="$WORK/out" mandisym="$BIN"
}
jobs_of() {  # jobs_of NAME STATE: how many jobs of that name ended in that state
  grep -c "Name=$1 JobState=$2 " "$STATE/jobcomp.txt" || true
}
show() { echo "--- $1"; cat "$1"; }

rc=0
sm > "$WORK/snakemake-1.log" 2>&1 || rc=$?
if [ "$rc" -ne 1 ]; then
  show "$WORK/snakemake-1.log"; show "$STATE/jobcomp.txt"; show "$STATE/slurmctld.log"
  fail "snakemake exited $rc, expected 1 (the corrupt study failed)"
fi
csv="$WORK/out/cohort.csv"
for s in sym ramus; do
  [ "$(jobs_of "mandisym-run_study-sid=$s" COMPLETED)" = 1 ] || { show "$STATE/jobcomp.txt"; fail "$s was not one completed sbatch job"; }
  grep -q "^\"$s\",\"done-earlier\",0," "$csv" || { show "$csv"; fail "$s not complete in cohort.csv"; }
done
[ "$(jobs_of "mandisym-run_study-sid=corrupt" FAILED)" = 2 ] ||
  { show "$STATE/jobcomp.txt"; fail "the corrupt study was not submitted twice (restart-times 1), failing both times"; }
slurm_logs=("$WORK/out/.logs/slurm/mandisym-run_study-sid=corrupt-"*.out)
[ "${#slurm_logs[@]}" = 2 ] || { ls "$WORK/out/.logs/slurm/"; fail "not two Slurm logs of the corrupt study"; }
grep -q '^"corrupt","failed",4,"mandisym: error: ' "$csv" || { show "$csv"; fail "the corrupt study is not listed as failed with exit code 4"; }
[ "$(grep -c '^"' "$csv")" = 3 ] || { show "$csv"; fail "cohort.csv does not list 3 studies"; }
for s in sym ramus; do grep -q "href=\"$s/report.html\"" "$WORK/out/cohort.html" || fail "cohort.html has no link to $s"; done
grep -q "corrupt" "$WORK/out/cohort.html" || fail "cohort.html does not list the corrupt study"

# Repaired, the study runs again (a failed study is never taken for done), and
# with every study complete the cohort files come from the cohort job.
rm -rf "$WORK/studies/corrupt" && ln -s "$WORK/gen/sym/dicom" "$WORK/studies/corrupt"
sm > "$WORK/snakemake-2.log" 2>&1 || { show "$WORK/snakemake-2.log"; show "$STATE/jobcomp.txt"; fail "the second run failed"; }
[ "$(jobs_of "mandisym-run_study-sid=corrupt" COMPLETED)" = 1 ] || { show "$STATE/jobcomp.txt"; fail "the repaired study was not run"; }
[ "$(jobs_of "mandisym-cohort-" COMPLETED)" = 1 ] || { show "$STATE/jobcomp.txt"; fail "no completed cohort job"; }
[ "$(grep -c 'Name=mandisym-run_study' "$STATE/jobcomp.txt")" = 5 ] || { show "$STATE/jobcomp.txt"; fail "the second run re-ran done studies"; }
[ "$(grep -c '^"[a-z]*","done-earlier",0,' "$csv")" = 3 ] || { show "$csv"; fail "cohort.csv after the second run"; }

pids=$(cat "$STATE"/*.pid)
trap - EXIT
"$SRC/scripts/slurm-local" stop "$STATE"
for p in $pids; do ! kill -0 "$p" 2>/dev/null || fail "daemon $p still running after slurm-local stop"; done
rm -rf "$STATE"
echo "ok: slurm workflow: 3 sbatch study jobs, the corrupt one failed twice (retried once) and is listed with exit 4; repaired, it ran alone, then the cohort job; daemons stopped"

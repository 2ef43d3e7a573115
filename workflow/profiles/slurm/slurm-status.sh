#!/usr/bin/env bash
# Snakemake's cluster-status for Slurm: prints running, success or failed for
# the job id that `sbatch --parsable` gave ("ID" or "ID;CLUSTER"). Always exits
# 0: Snakemake stops the whole workflow when this command fails.
#
# Where the state comes from, in turn:
#   1. sacct (sites with slurmdbd; "Slurm accounting storage is disabled"
#      otherwise, or empty while a fresh job is not in the database yet);
#   2. scontrol show job (the controller keeps a finished job for MinJobAge,
#      300 s by default);
#   3. the jobcomp/filetxt record (JobCompLoc), where a site writes one;
#   4. still unknown: failed, so Snakemake retries it (restart-times), unless
#      the controller did not answer at all: running, asked again next poll.
# Every end other than COMPLETED is failed: FAILED (non-zero exit), CANCELLED
# (scancel, or a job Slurm ended), TIMEOUT, OUT_OF_MEMORY, NODE_FAIL,
# BOOT_FAIL, DEADLINE, PREEMPTED; a job that could not even open its --output
# file ends FAILED with ExitCode 0:53.
id=${1%%;*}
state=$(sacct -n -X -P -j "$id" -o State 2>/dev/null | head -n 1)
if [ -z "$state" ]; then
  if info=$(scontrol show job -o "$id" 2>&1); then
    state=$(grep -o 'JobState=[A-Z_]*' <<<"$info" | head -n 1)
    state=${state#JobState=}
  elif ! grep -qi 'invalid job id' <<<"$info"; then
    echo running  # the controller did not answer (restarting, overloaded): ask again
    exit 0
  fi
fi
if [ -z "$state" ]; then
  loc=$(scontrol show config 2>/dev/null | awk '$1 == "JobCompLoc" { print $3 }')
  if [ -f "$loc" ]; then
    state=$(grep "^JobId=$id " "$loc" | tail -n 1 | grep -o 'JobState=[A-Z_]*')
    state=${state#JobState=}
  fi
fi
case "${state%% *}" in
  COMPLETED) echo success ;;
  PENDING | CONFIGURING | RUNNING | COMPLETING | SUSPENDED | REQUEUED | REQUEUE_HOLD | REQUEUE_FED | RESIZING | \
    SIGNALING | STAGE_OUT | STOPPED | RESV_DEL_HOLD | SPECIAL_EXIT)
    echo running ;;
  *) echo failed ;;
esac
exit 0

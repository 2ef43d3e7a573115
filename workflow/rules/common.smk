# The cohort workflow's configuration, study list and jobs (workflow/Snakefile).
# Study ids, folders, per-study options, timeouts and the OUT/.done/<id>
# record follow `mandisym batch` exactly (pipeline/batch_cmd.cpp,
# docs/batch.md), so batch and Snakemake can share one OUT folder.
import contextlib
import csv
import glob
import math
import os
import re
import shlex
import signal
import subprocess
import time

from snakemake.exceptions import WorkflowError

SOURCE = config["source"]
OUT = config["out"]
MANDISYM = config.get("mandisym", "mandisym")
# Options for every study's `mandisym run`, as after `mandisym batch ... --`
# (a string split like a shell would, or a list).
RUN_ARGS = config.get("run_args", "")
RUN_ARGS = shlex.split(RUN_ARGS) if isinstance(RUN_ARGS, str) else [str(a) for a in RUN_ARGS]
# Threads of each study's run (`run --threads`; Snakemake lowers it to --cores).
THREADS_PER_STUDY = int(config.get("threads_per_study", 2))
# Per-study timeout, s (docs/batch.md, "Timeouts"): auto = 600 s + 1 s per MB
# of the study's files, as `mandisym batch`; 0 = none.
STUDY_TIMEOUT = str(config.get("study_timeout", "auto"))
DEFAULT_TIMEOUT_S = 600  # floor: 45x the slowest documented end-to-end run
TIMEOUT_S_PER_MB = 1.0  # 12x the slowest documented s/MB (README, "Speed")
KILL_GRACE_S = 5  # SIGTERM, then SIGKILL this much later (as batch)
# Exit codes of `mandisym run` after which results.json is written: 0, and
# 8 = the result failed quality control (docs/qc.md).
RUN_WROTE_RESULTS = (0, 8)
# CSV columns that give a study its own run option, in batch's order; `mask`
# is relative to the CSV's folder, as `path` is. An empty cell keeps run_args.
STUDY_OPTION_COLUMNS = (
    ("mask", "--mask"),
    ("label", "--label"),
    ("hu_offset", "--hu-offset"),
    ("orientation", "--orientation"),
    ("series", "--series"),
)
# Set by the workflow itself for every study (as batch refuses them after --).
WORKFLOW_OWNED_OPTIONS = ("-o", "--output", "--threads")


def refuse_owned_options(args):
    for a in args:
        if a in WORKFLOW_OWNED_OPTIONS or a.startswith(("--output=", "--threads=")):
            raise WorkflowError(
                f"run_args: {a} is set by the workflow itself (OUT/<id>; threads_per_study)"
            )


def safe_id(s):
    s = re.sub(r"[^A-Za-z0-9._-]", "_", s)
    return f"_{s}" if (not s or s[0] == ".") else s


def read_csv_studies(source):
    """(id, path, own run options) of each row of a CSV source, as batch."""
    base = os.path.dirname(source)
    rows = []
    with open(source, newline="") as f:
        reader = csv.DictReader(f)
        if "path" not in (reader.fieldnames or []):
            raise WorkflowError(f"{source}: the CSV needs a header with columns id,path")
        for row in reader:
            if not any((v or "").strip() for v in row.values() if isinstance(v, str)):
                continue
            path = row["path"] or ""
            if not os.path.isabs(path):
                path = os.path.join(base, path)
            options = []
            for column, option in STUDY_OPTION_COLUMNS:
                value = row.get(column) or ""
                if not value:
                    continue
                if column == "mask" and not os.path.isabs(value):
                    value = os.path.join(base, value)
                options += [option, value]
            rows.append((row.get("id") or os.path.basename(path), path, options))
    return rows


def list_studies(source):
    """{id: {"path", "options"}} in batch's order, ids made safe and unique."""
    if os.path.isdir(source):
        rows = [
            (name, os.path.join(source, name), [])
            for name in sorted(os.listdir(source))
            if not name.startswith(".")
        ]
    elif os.path.isfile(source):
        rows = read_csv_studies(source)
    else:
        raise WorkflowError(f"{source}: no such folder or CSV file")
    if not rows:
        raise WorkflowError(f"{source}: no studies found")
    studies, seen = {}, {}
    for name, path, options in rows:
        sid = safe_id(name)
        seen[sid] = seen.get(sid, 0) + 1
        if seen[sid] > 1:
            sid = f"{sid}_{seen[sid]}"
        studies[sid] = {"path": path, "options": options}
    return studies


def study_bytes(path):
    """Bytes of the study's regular files (never opened); None when unknown."""
    if os.path.isfile(path):
        return os.path.getsize(path)
    if not os.path.isdir(path):
        return None  # FIFO, device, missing
    total = 0
    for base, _, files in os.walk(path, followlinks=False):
        for name in files:
            p = os.path.join(base, name)
            if os.path.isfile(p):
                total += os.path.getsize(p)
    return total


def study_timeout(sid):
    if STUDY_TIMEOUT != "auto":
        return int(float(STUDY_TIMEOUT))
    size = study_bytes(STUDIES[sid]["path"])
    return int(DEFAULT_TIMEOUT_S + (TIMEOUT_S_PER_MB * size / 1e6 if size else 0))


def study_runtime_min(wildcards):
    """Slurm --time: the study's timeout plus 5 minutes, at least 30."""
    return max(30, math.ceil(study_timeout(wildcards.sid) / 60) + 5)


def study_argv(sid, threads):
    study = STUDIES[sid]
    return [MANDISYM, "run", study["path"], "-o", os.path.join(OUT, sid), "-q",
            "--threads", str(threads)] + RUN_ARGS + study["options"]


def process_tree(pid):
    """pid and every process under it (Linux: /proc/PID/task/TID/children)."""
    tree, todo = [], [pid]
    while todo:
        p = todo.pop()
        tree.append(p)
        for children in glob.glob(os.path.join(os.sep, "proc", str(p), "task", "*", "children")):
            with contextlib.suppress(OSError), open(children) as f:
                todo += [int(c) for c in f.read().split()]
    return tree


def signal_all(pids, sig):
    for p in pids:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.kill(p, sig)


def wait_for_study(child, limit_s):
    """The child's exit code; 128+N when signal N ended it. After limit_s > 0
    seconds, it and what it started (its Xvfb) get SIGTERM, SIGKILL 5 s later
    (as batch), and the exit code is 124 (GNU timeout's)."""
    try:
        rc = child.wait(timeout=limit_s if limit_s > 0 else None)
    except subprocess.TimeoutExpired:
        tree = process_tree(child.pid)
        signal_all(tree, signal.SIGTERM)
        with contextlib.suppress(subprocess.TimeoutExpired):
            child.wait(timeout=KILL_GRACE_S)
        signal_all(tree, signal.SIGKILL)
        child.wait()
        return 124
    return 128 - rc if rc < 0 else rc


def run_study(sid, log, threads):
    """One study's job: `mandisym run`, its output in LOG, "EXIT SECONDS" in
    OUT/.done/<id> (read by `batch --aggregate-only`). Fails (so Snakemake
    retries it, restart-times) unless results.json was written; the study's
    folder is OUT/<id>, as batch's. The run stays in Snakemake's process group,
    as a shell job would: Ctrl-C reaches it, and Slurm signals every process of
    the job anyway."""
    done = os.path.join(OUT, ".done", sid)
    os.makedirs(os.path.dirname(done), exist_ok=True)
    with contextlib.suppress(FileNotFoundError):
        os.remove(done)  # an earlier attempt's
    start = time.monotonic()
    with open(log, "wb") as f:
        child = subprocess.Popen(study_argv(sid, threads), stdin=subprocess.DEVNULL, stdout=f,
                                 stderr=subprocess.STDOUT)
        rc = wait_for_study(child, study_timeout(sid))
    with open(done, "w") as f:
        f.write(f"{rc} {time.monotonic() - start:.1f}\n")
    if rc not in RUN_WROTE_RESULTS:
        what = "timed out" if rc == 124 else f"exited with {rc}"
        raise WorkflowError(f"study {sid}: mandisym run {what} (its log: {log})")


def aggregate(log):
    """cohort.csv and cohort.html from what is in OUT (`batch --aggregate-only`;
    its exit 9 only says that some study failed)."""
    argv = [MANDISYM, "batch", SOURCE, "-o", OUT, "--aggregate-only", "-q"]
    os.makedirs(os.path.dirname(log), exist_ok=True)
    with open(log, "wb") as f:
        rc = subprocess.run(argv, stdin=subprocess.DEVNULL, stdout=f, stderr=subprocess.STDOUT).returncode
    if rc not in (0, 9):
        raise WorkflowError(f"the cohort files: mandisym batch --aggregate-only exited with {rc} (its log: {log})")


def aggregate_after_failure():
    """onerror: with a study failed for good, rule cohort cannot run; the
    cohort files are written here instead, listing it with its exit code."""
    try:
        aggregate(COHORT_LOG)
        print(f"MandiSym: cohort files written despite failed jobs: {os.path.join(OUT, 'cohort.html')}")
    except (OSError, WorkflowError) as e:
        print(f"MandiSym: the cohort files could not be written: {e}")


def check_options():
    """Every study's run options (run_args and the CSV's columns), checked by
    `mandisym batch --check-only` as batch checks them, before any job is
    submitted: a bad value stops the workflow here, not in every job."""
    argv = [MANDISYM, "batch", SOURCE, "-o", OUT, "--check-only", "-q", "--"] + RUN_ARGS
    try:
        done = subprocess.run(argv, capture_output=True, text=True, timeout=120)
    except OSError as e:
        raise WorkflowError(f"cannot run {MANDISYM}: {e}")
    if done.returncode != 0:
        raise WorkflowError(f"run options refused: {(done.stderr or done.stdout).strip()}")


refuse_owned_options(RUN_ARGS)
STUDIES = list_studies(SOURCE)
check_options()
# Not a study's: safe ids never start with a dot.
COHORT_LOG = os.path.join(OUT, ".logs", ".cohort.log")

#!/usr/bin/env bash
# Held-out scores and final teams for compact results committed before those features (issues 33 and 43): every job
# of RESULTS (default results/paper; also results/selectors, results/geometry) whose dir name matches JOBS (a shell
# pattern, default *) is recomputed from its own overrides (`studies/heldout/report.py overrides JOB_DIR`: read from its
# config.yaml and summary.json and allow-listed, never from its dir name) into OUT, one job at a time on the embedded
# Ray, then `python studies/heldout/report.py merge OUT RESULTS` adds each run's held-out score to the committed
# summary.json and the runs' final teams as genomes.npz, after checking that every recomputed run ends at the
# committed final score. Resumable, also across sessions: a job of RESULTS with held-out scores and genomes.npz is
# skipped; one whose runs are in OUT resumes there. Commit RESULTS between sessions.
# Usage: [RESULTS=results/paper] [OUT=outputs/heldout/<name>] [SEEDS=16] [JOBS='env.obs_radius=4,*']
#        launchers/heldout.sh [HYDRA_OVERRIDE ...]
set -euo pipefail
RESULTS="${RESULTS:-results/paper}"
OUT="${OUT:-outputs/heldout/$(basename "$RESULTS")}"
SEEDS="${SEEDS:-16}"
PYTHON="${PYTHON:-python}"
JOBS="${JOBS:-*}"
MIGRATION="$(cd "$(dirname "$0")/.." && pwd)/studies/heldout/report.py"
[ -d "$RESULTS" ] || { echo "$(basename "$0"): error: RESULTS=$RESULTS: no such directory" >&2; exit 2; }
for summary in "$RESULTS"/$JOBS/summary.json; do
    [ -f "$summary" ] || continue
    name="$(basename "$(dirname "$summary")")"
    shown="${name@Q}"                                                     # a name's control characters escaped
    status=0
    "$PYTHON" "$MIGRATION" done "$RESULTS/$name" || status=$?          # 0: held-out scores; 3: none; else a failure
    if [ "$status" -ne 0 ] && [ "$status" -ne 3 ]; then
        echo "$(basename "$0"): $shown: $MIGRATION done failed (exit $status, above): stopped" >&2
        exit "$status"
    fi
    if [ -f "$RESULTS/$name/genomes.npz" ] && [ "$status" -eq 0 ]; then
        echo "$(basename "$0"): $shown has held-out scores and final teams: skipped" >&2
        continue
    fi
    # the job's overrides from its own files (config.yaml, summary.json), each allow-listed; never from its name
    if ! listed="$("$PYTHON" "$MIGRATION" overrides "$RESULTS/$name")"; then
        echo "$(basename "$0"): $shown: its overrides cannot be read (above): skipped" >&2
        continue
    fi
    overrides=()
    [ -z "$listed" ] || mapfile -t overrides <<< "$listed"
    "$PYTHON" -m rovermarl.train "${overrides[@]}" "seeds=$SEEDS" "hydra.run.dir='$OUT/$name'" "$@"   # quoted: = and ,
    "$PYTHON" "$MIGRATION" merge "$OUT" "$RESULTS"
done

#!/usr/bin/env bash
# Held-out scores for compact results committed before the feature (issue 33): every job of RESULTS (default
# results/paper; also results/selectors) is recomputed from its own overrides (its dir name) into OUT, one job at a
# time on the embedded Ray, then `python -m rovermarl.analysis heldout merge OUT RESULTS` adds each run's held-out
# score to the committed summary.json, after checking that every recomputed run ends at the committed final score.
# Resumable, also across sessions: a job whose summary.json in RESULTS has held-out scores is skipped; one whose runs
# are in OUT resumes there. Commit RESULTS between sessions.
# Usage: [RESULTS=results/paper] [OUT=outputs/heldout/<name>] [SEEDS=16] launchers/heldout.sh [HYDRA_OVERRIDE ...]
set -euo pipefail
RESULTS="${RESULTS:-results/paper}"
OUT="${OUT:-outputs/heldout/$(basename "$RESULTS")}"
SEEDS="${SEEDS:-16}"
PYTHON="${PYTHON:-python}"
[ -d "$RESULTS" ] || { echo "$(basename "$0"): error: RESULTS=$RESULTS: no such directory" >&2; exit 2; }
for summary in "$RESULTS"/*/summary.json; do
    name="$(basename "$(dirname "$summary")")"
    if "$PYTHON" -c 'import json, sys; sys.exit(0 if json.load(open(sys.argv[1])).get("heldout_score") else 1)' \
        "$summary"; then
        echo "$(basename "$0"): $name has held-out scores: skipped" >&2
        continue
    fi
    IFS=, read -r -a overrides <<< "$name"
    "$PYTHON" -m rovermarl.train "${overrides[@]}" "seeds=$SEEDS" "hydra.run.dir='$OUT/$name'" "$@"   # quoted: = and ,
    "$PYTHON" -m rovermarl.analysis heldout merge "$OUT" "$RESULTS"
done

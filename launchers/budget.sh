#!/usr/bin/env bash
# The budget study: does setup duo reach the paper's scores with ten times the paper's budget? Setup duo with k=1,
# k=2, EXP3-adaptive k and the homogeneous team at 2,000,000 generations: 4 jobs. One job at a time; after each, the
# compact results of every finished job of OUT go into RESULTS (python -m rovermarl.analysis export, without the
# Fig. 6 data): RESULTS/<job>/{summary.json,config.yaml,curves.npz} and RESULTS/compute.json.
# Resumable, also across machines and sessions: a job whose compact files are in RESULTS is skipped, one whose runs
# are in OUT resumes there. Commit RESULTS between sessions and the study goes on where it stopped.
# Usage: [GENERATIONS=N (default 2000000)] [SEEDS=S] [OUT=DIR] [RESULTS=DIR] launchers/budget.sh [HYDRA_OVERRIDE ...]
# Only the committed study's budget (GENERATIONS=2000000 SEEDS=16) refreshes results/budget; any other writes to
# outputs/results/budget_g<N>_s<S>[,...] (results_dir in _sweep.sh).
GENERATIONS="${GENERATIONS:-2000000}"
OUT="${OUT:-outputs/budget}"
# shellcheck source=launchers/_sweep.sh
source "$(dirname "$0")/_sweep.sh"
results_dir budget 2000000 16 "$@"


for method in k=1 k=2 k=adaptive team=homogeneous; do
    compact_job "$method" setup=duo "$@"
done

#!/usr/bin/env bash
# The geometry study (issue 33): does setup duo reproduce under another world geometry? Setup duo with k=1, k=2 and
# the homogeneous team, for every observation radius (env.obs_radius 2, 3, 4) x POI circle radius (env.poi_distance
# 13, 9): 18 jobs. One job at a time; after each, the compact results of every finished job of OUT go into RESULTS
# (python -m rovermarl.analysis export, without the Fig. 6 data): RESULTS/<job>/{summary.json,config.yaml,curves.npz}
# and RESULTS/compute.json.
# Resumable, also across machines and sessions: a job whose compact files are in RESULTS is skipped, one whose runs
# are in OUT resumes there. Commit RESULTS between sessions and the study goes on where it stopped.
# Usage: [GENERATIONS=N (default 200000)] [SEEDS=S] [OUT=DIR] [RESULTS=DIR] launchers/geometry.sh [HYDRA_OVERRIDE ...]
# Only the committed study's budget (GENERATIONS=200000 SEEDS=16) refreshes results/geometry; any other writes to
# outputs/results/geometry_g<N>_s<S>[,...] (results_dir in _sweep.sh).
OUT="${OUT:-outputs/geometry}"
# shellcheck source=launchers/_sweep.sh
source "$(dirname "$0")/_sweep.sh"
results_dir geometry 200000 16 "$@"

job_name() {  # job_name OVERRIDE...: the job's dir name under OUT (and RESULTS), as rovermarl.train names it
    "$PYTHON" -c 'import sys; from rovermarl.config import dirname, quote_numeric_options
print(dirname(quote_numeric_options(sys.argv[1:])))' "$@"
}

for radius in 2 3 4; do
    for distance in 13 9; do
        for method in k=1 k=2 team=homogeneous; do
            overrides=("$method" setup=duo "env.obs_radius=$radius" "env.poi_distance=$distance")
            name="$(job_name "${overrides[@]}" "generations=$GENERATIONS" "$@")"
            if [ -f "$RESULTS/$name/summary.json" ] && [ -f "$RESULTS/$name/curves.npz" ]; then
                echo "$(basename "$0"): $name is in $RESULTS: skipped" >&2
                continue
            fi
            sweep "${overrides[@]}" "$@"
            "$PYTHON" -m rovermarl.analysis export "$OUT" "$RESULTS" --generations "$GENERATIONS" --no-fig6
        done
    done
done

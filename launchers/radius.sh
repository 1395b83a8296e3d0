#!/usr/bin/env bash
# The pre-registered radius study (issue 43): at the paper's POI circle (env.poi_distance=13), which observation
# radius env.obs_radius in 2.5, 3, 3.5, 4 gives the paper's picture? In each world: duo k=1, k=2 and the homogeneous
# team, solo k=1, k=4 and the homogeneous team; 200,000 generations, 16 runs on seeds 16-31 (seed=16: no committed
# study used them). 24 jobs, one at a time; after each, the compact results of every finished job of OUT go into
# RESULTS (python -m rovermarl.analysis export, with each run's final team): RESULTS/<job>/{summary.json,
# config.yaml,curves.npz,genomes.npz} and RESULTS/compute.json.
# The criteria were fixed before any run (issue 43; python studies/radius/report.py reports them). A radius
# reproduces the paper's picture only if all four hold:
#   1. duo k=1 and k=2 each have at least 8 of 16 runs ending at 5 or more;
#   2. at least one duo k=1 or k=2 run ends at 6;
#   3. solo k=1 has at least 12 of 16 runs reaching 4;
#   4. solo homogeneous and solo k=4 each have at most 3 of 16 runs reaching 4.
# Resumable, also across machines and sessions: a job whose compact files are in RESULTS is skipped, one whose runs
# are in OUT resumes there. Commit RESULTS between sessions and the study goes on where it stopped.
# Usage: [GENERATIONS=N (default 200000)] [SEEDS=S] [OUT=DIR] [RESULTS=DIR] [RADII="R ..."]
#        launchers/radius.sh [HYDRA_OVERRIDE ...]
# Only the committed study's budget (GENERATIONS=200000 SEEDS=16) refreshes results/radius; any other writes to
# outputs/results/radius_g<N>_s<S>[,...] (results_dir in _sweep.sh).
OUT="${OUT:-outputs/radius}"
RADII="${RADII:-2.5 3 3.5 4}"
# shellcheck source=launchers/_sweep.sh
source "$(dirname "$0")/_sweep.sh"
results_dir radius 200000 16 "$@"
for radius in $RADII; do   # fail before any work on a malformed radius
    [[ "$radius" =~ ^[0-9]+(\.[0-9]+)?$ ]] || { echo "$(basename "$0"): error: RADII: '$radius' is not a number" >&2; exit 2; }
done

job() {  # job SETUP RADIUS METHOD EXTRA...: one job (compact_job in _sweep.sh)
    local overrides=("$3" "setup=$1" "env.obs_radius=$2" "env.poi_distance=13" "seed=16")
    shift 3
    compact_job "${overrides[@]}" "$@"
}

for radius in $RADII; do
    for method in k=1 k=2 team=homogeneous; do
        job duo "$radius" "$method" "$@"
    done
    for method in k=1 k=4 team=homogeneous; do
        job solo "$radius" "$method" "$@"
    done
done

#!/usr/bin/env bash
# The geometry study (issue 33): does setup duo reproduce under another world geometry? Setup duo with k=1, k=2 and
# the homogeneous team, for every observation radius (env.obs_radius 2, 3, 4) x POI circle radius (env.poi_distance
# 13, 9): 18 jobs. One job at a time; after each, the compact results of every finished job of OUT go into RESULTS
# (python -m rovermarl.analysis export, without the Fig. 6 data): RESULTS/<job>/{summary.json,config.yaml,curves.npz}
# and RESULTS/compute.json.
# Resumable, also across machines and sessions: a job whose compact files are in RESULTS is skipped, one whose runs
# are in OUT resumes there. Commit RESULTS between sessions and the study goes on where it stopped.
# Then setup solo with the same methods, budget and seeds for each geometry "R,D" (env.obs_radius=R,
# env.poi_distance=D) in SOLO_GEOMETRIES (default "4,13", the world where duo gives the paper's picture): does solo
# still reach the paper's all-solo optimum 4 there? 3 jobs per geometry, into the same OUT and RESULTS.
# Usage: [GENERATIONS=N (default 200000)] [SEEDS=S] [OUT=DIR] [RESULTS=DIR] [SOLO_GEOMETRIES="R,D ..."]
#        launchers/geometry.sh [HYDRA_OVERRIDE ...]
# Only the committed study's budget (GENERATIONS=200000 SEEDS=16) refreshes results/geometry; any other writes to
# outputs/results/geometry_g<N>_s<S>[,...] (results_dir in _sweep.sh).
OUT="${OUT:-outputs/geometry}"
SOLO_GEOMETRIES="${SOLO_GEOMETRIES:-4,13}"
# shellcheck source=launchers/_sweep.sh
source "$(dirname "$0")/_sweep.sh"
results_dir geometry 200000 16 "$@"
for geometry in $SOLO_GEOMETRIES; do   # fail before any work on a malformed geometry
    [[ "$geometry" =~ ^[0-9.]+,[0-9.]+$ ]] || { echo "$(basename "$0"): error: SOLO_GEOMETRIES: '$geometry' is not R,D" >&2; exit 2; }
done

job() {  # job SETUP RADIUS DISTANCE METHOD EXTRA...: one job (compact_job in _sweep.sh)
    local overrides=("$4" "setup=$1" "env.obs_radius=$2" "env.poi_distance=$3")
    shift 4
    compact_job "${overrides[@]}" "$@"
}

for radius in 2 3 4; do            # duo: every geometry
    for distance in 13 9; do
        for method in k=1 k=2 team=homogeneous; do
            job duo "$radius" "$distance" "$method" "$@"
        done
    done
done
for geometry in $SOLO_GEOMETRIES; do   # solo: the geometries of SOLO_GEOMETRIES
    for method in k=1 k=2 team=homogeneous; do
        job solo "${geometry%,*}" "${geometry#*,}" "$method" "$@"
    done
done

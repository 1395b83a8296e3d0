#!/usr/bin/env bash
# The learners study (issues 44 and 54, docs/LEARNERS.md): every coordination world x every family of learner at one
# budget of agent-steps (budget.agent_steps: a team evaluation is episodes x steps x rovers = 960 agent-steps for 4
# rovers), SEEDS runs each, every final team also scored on its run's 256 held-out initial conditions.
#   Worlds:   solo, duo, trio (conf/setup), obstacles, random_pois, moving_pois (examples/).
#   Learners: CC-(1+1)-ES k=1, k=adaptive and homogeneous; the CCEA with D++; sep-CMA-ES over the team; PPO with
#             parameter sharing (stable-baselines3: pip install -e ".[rl]"); MAPPO and IPPO (TorchRL: pip install -e
#             ".[marl]"). A learner whose extra is not installed is skipped with a message.
#   Regimes:  fixed (evaluation.fresh_ic=false: each run trains on its 16 initial conditions; PPO's environments start
#             from them in turn) on every world; fresh (evaluation.fresh_ic=true: new initial conditions every
#             generation, the kept team re-scored beside the new ones) on FRESH_WORLDS (solo, duo, trio).
#   Final team: the best kept so far for every learner (CC-ES and sep-CMA-ES are elitist; the CCEA, PPO, MAPPO and
#             IPPO are told algorithm.final_team=best).
# Jobs run learner by learner, the RL learners last (they take ~20x the others' time). After each, the compact results of every
# finished job of OUT go into RESULTS (python -m rovermarl.analysis export), then docs/LEARNERS.md is regenerated.
# Resumable, also across machines and sessions: a job whose compact files are in RESULTS, made from a committed tree
# (provenance dirty: false) with its regime recorded, is skipped; any other is (re)computed, its runs resuming in OUT
# from their checkpoints. Commit RESULTS between sessions and the study goes on where it stopped.
# Usage: [AGENT_STEPS=N (default 19200000)] [SEEDS=S (default 8)] [OUT=DIR] [RESULTS=DIR] [WORLDS="solo ..."]
#        [FRESH_WORLDS="solo duo trio"] [REGIMES="fixed fresh"] [LEARNERS="cces_k1 ..."]
#        [PARALLEL="parallel=ray ray.num_cpus=2" (default parallel=serial)] [DOC=docs/LEARNERS.md]
#        launchers/learners.sh [HYDRA_OVERRIDE ...]
# A run that must stay clean (provenance dirty: false) while it writes keeps RESULTS and DOC outside the tracked tree
# (e.g. RESULTS=/scratch/learners DOC=/scratch/LEARNERS.md, a copy of docs/LEARNERS.md), then copies them in.
# Only the committed study's budget (AGENT_STEPS=19200000 SEEDS=8) refreshes results/learners; any other writes to
# outputs/results/learners_g<AGENT_STEPS>_s<S>[,...] (results_dir in _sweep.sh).
AGENT_STEPS="${AGENT_STEPS:-19200000}"
SEEDS="${SEEDS:-8}"
GENERATIONS="$AGENT_STEPS"                     # what results_dir compares with the committed study's budget
OUT="${OUT:-outputs/learners}"
WORLDS="${WORLDS:-solo duo trio obstacles random_pois moving_pois}"
FRESH_WORLDS="${FRESH_WORLDS:-solo duo trio}"
REGIMES="${REGIMES:-fixed fresh}"
DOC="${DOC:-docs/LEARNERS.md}"                 # where the report so far goes
PARALLEL="${PARALLEL:-parallel=serial}"        # how a job's seeds run: one after another, or on Ray
LEARNERS="${LEARNERS:-cces_k1 cces_adaptive cces_homogeneous ccea_dpp cma ppo mappo ippo}"
# shellcheck source=launchers/_sweep.sh
source "$(dirname "$0")/_sweep.sh"
results_dir learners 19200000 8 "$@"

world() {  # world NAME: its overrides (empty: not available here)
    case "$1" in
        solo | duo | trio) echo "setup=$1" ;;
        obstacles | random_pois | moving_pois)
            [ -d "examples/$1" ] && echo "env=$1 hydra.searchpath=[file://examples/$1]" ;;
        *) echo "$(basename "$0"): error: WORLDS: no world '$1'" >&2; exit 2 ;;
    esac
}

learner() {  # learner NAME: its overrides
    case "$1" in
        cces_k1) echo "k=1" ;;
        cces_adaptive) echo "k=adaptive" ;;
        cces_homogeneous) echo "team=homogeneous" ;;
        ccea_dpp) echo "algorithm=ccea algorithm.reward=dpp +algorithm.final_team=best" ;;
        cma) echo "algorithm=cma" ;;
        ppo | mappo | ippo) echo "algorithm=$1 +algorithm.final_team=best checkpoint.every=25 parallel.chunk=25" ;;
        *) echo "$(basename "$0"): error: LEARNERS: no learner '$1'" >&2; exit 2 ;;
    esac
}


regime() {  # regime NAME: its overrides (fixed is the default: its job names are those of the first study)
    case "$1" in
        fixed) echo "" ;;
        fresh) echo "evaluation.fresh_ic=true" ;;
        *) echo "$(basename "$0"): error: REGIMES: no regime '$1'" >&2; exit 2 ;;
    esac
}

done_clean() {  # done_clean JOB_DIR: 0 if its compact files are there, made from a committed tree, its regime
    # recorded; 3 if not; any other status is a failure (an unreadable summary.json, a broken install)
    [ -f "$1/summary.json" ] && [ -f "$1/curves.npz" ] || return 3
    "$PYTHON" -c '
import sys
from rovermarl.record.safe_read import read_json
try:
    s = read_json(sys.argv[1], kind="summary")
except Exception as e:                                          # one line, not a traceback (it names the file)
    sys.exit(str(e))
prov = s.get("provenance")
sys.exit(0 if s.get("train_ic") in ("fixed", "fresh") and isinstance(prov, dict) and prov.get("dirty") is False else 3)
' "$1/summary.json"
}

extra() {  # extra NAME: the modules a learner needs and its extra ("" when it needs none)
    case "$1" in
        ppo) echo "torch,stable_baselines3 rl" ;;
        mappo | ippo) echo "torch,torchrl marl" ;;
    esac
}

ordered=()
for l in $LEARNERS; do case "$l" in ppo | mappo | ippo) ;; *) ordered+=("$l") ;; esac; done
for l in $LEARNERS; do case "$l" in ppo | mappo | ippo) ordered+=("$l") ;; esac; done
for l in "${ordered[@]}"; do
    read -ra lo <<< "$(learner "$l")"
    read -r modules ext <<< "$(extra "$l")"
    if [ -n "$modules" ] && ! "$PYTHON" -c "import $modules" 2>/dev/null; then
        echo "$(basename "$0"): $l: $modules not installed (pip install -e \".[$ext]\"): skipped" >&2
        continue
    fi
    for r in $REGIMES; do
        read -ra ro <<< "$(regime "$r")"
        for w in $WORLDS; do
            if [ "$r" = fresh ] && [[ " $FRESH_WORLDS " != *" $w "* ]]; then
                continue
            fi
            read -ra wo <<< "$(world "$w")"
            if [ "${#wo[@]}" -eq 0 ]; then
                echo "$(basename "$0"): world $w: examples/$w does not exist yet: skipped" >&2
                continue
            fi
            read -ra par <<< "$PARALLEL"
            overrides=("${wo[@]}" "${lo[@]}" "${ro[@]}" "budget.agent_steps=$AGENT_STEPS" "record=off" "${par[@]}")
            name="$(job_name "${overrides[@]}" "seeds=$SEEDS")"
            status=0
            done_clean "$RESULTS/$name" || status=$?
            if [ "$status" -eq 0 ]; then
                echo "$(basename "$0"): $name is in $RESULTS (clean, regime recorded): skipped" >&2
                continue
            elif [ "$status" -ne 3 ]; then
                echo "$(basename "$0"): $name: the done check failed (exit $status, above): stopped" >&2
                exit 1
            fi
            "$PYTHON" -m rovermarl.train -m "${overrides[@]}" "seeds=$SEEDS" "hydra.sweep.dir=$OUT" "$@"
            "$PYTHON" -m rovermarl.analysis export "$OUT" "$RESULTS" --no-fig6 --trust-config
            "$PYTHON" "$STUDIES"/learners/report.py "$RESULTS" --doc "$DOC" || true   # the report so far
        done
    done
done

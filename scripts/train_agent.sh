#!/usr/bin/env bash
# Train one algorithm on one environment id with `food-fetch train` (hyperparameters from
# agents/hyperparams/<algo>.yml), then evaluate the saved model on the held-out headroom
# scenes (seed 80000, the reporting seeds of benchmarks/headroom.py) so that its mean reward
# sits beside random, study, model-based and search in docs/data/headroom.json.
#
#   scripts/train_agent.sh FoodFetch-Block-v1 sac            # budget: the YAML's n_timesteps
#   STEPS=15000 scripts/train_agent.sh FoodFetch-Block-v1 ppo
#   OVERWRITE=1 scripts/train_agent.sh FoodFetch-Row-v1 sac  # train again into a used folder
#   SKIP_EVAL=1 ...                                           # train only
#
# Writes out/<algo>_<id>/ (model.zip, config.yml, logs), out/<algo>_<id>/heldout.json and
# heldout.episodes.jsonl (each scene's reward, for scripts/add_trained_agent.py --paired-with);
# the wall time of training is printed and stored in train_wall.txt beside the model.
set -euo pipefail
ENV_ID="${1:?usage: scripts/train_agent.sh ENV_ID ALGO}"
ALGO="${2:?usage: scripts/train_agent.sh ENV_ID ALGO}"
SEED="${SEED:-0}"
OUT="${OUT:-out/${ALGO}_${ENV_ID}}"
EPISODES="${EPISODES:-200}"
EVAL_SEED="${EVAL_SEED:-80000}"
mkdir -p "$OUT"
args=(--algo "$ALGO" --env "$ENV_ID" --seed "$SEED" --log-dir "$OUT" --no-progress)
[[ -n "${STEPS:-}" ]] && args+=(--timesteps "$STEPS")
[[ "${OVERWRITE:-0}" == 1 ]] && args+=(--overwrite)
start=$(date +%s)
food-fetch train "${args[@]}"
wall=$(( $(date +%s) - start ))
echo "$wall" > "$OUT/train_wall.txt"
echo "training wall time: $wall s"
if [[ "${SKIP_EVAL:-0}" != 1 ]]; then
    food-fetch evaluate --agent "$OUT/model.zip" --env "$ENV_ID" --episodes "$EPISODES" \
        --seed "$EVAL_SEED" --workers "${WORKERS:-1}" --json "$OUT/heldout.json" \
        --episodes-log "$OUT/heldout.episodes.jsonl"
fi

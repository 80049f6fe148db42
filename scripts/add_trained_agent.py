"""Put a trained agent's held-out evaluation beside the baselines in docs/data/headroom.json.

    python scripts/add_trained_agent.py out/sac_FoodFetch-Block-v1 --algo sac

reads what ``scripts/train_agent.sh`` left in the run folder (``heldout.json``: the model on
the 200 headroom scenes; ``model.zip``: the fetches it was trained on, which differ from the
budget where a run was stopped early or a PPO run ended on a whole rollout; ``config.yml``:
the training budget, the total when resumed; ``train_wall.txt``: the training's wall time in
seconds, the total of every part) and
stores the agent's summary under ``results[ID]["agents"][ALGO]`` and how it was trained
under ``results[ID]["trained"][ALGO]``.  Refused unless the evaluation used the same
scenes (environment id, seed, episodes, env kwargs) as the id's headroom run.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import zipfile
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
HEADROOM = ROOT / "docs" / "data" / "headroom.json"


def _rewards(log: Path, agent: str | None = None) -> dict[int, float]:
    """Each scene's reward in an episode log (JSON Lines), by seed; ``agent`` keeps only
    that agent's episodes (a log of several agents holds each seed once per agent)."""
    rows = [json.loads(line) for line in log.read_text().splitlines()[1:] if line.strip()]
    if agent is not None:
        rows = [r for r in rows if r.get("agent") == agent]
    by_seed = {int(r["seed"]): float(r["reward"]) for r in rows}
    if len(by_seed) != len(rows):
        sys.exit(f"{log}: a seed appears more than once; give one agent's episodes")
    return by_seed


def _paired(agent_log: Path, baseline_log: Path) -> dict[str, object]:
    """The agent's reward less model-based's, paired on the scenes both ran."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from headroom import paired_difference

    a, b = _rewards(agent_log), _rewards(baseline_log, agent="model-based")
    seeds = sorted(set(a) & set(b))
    return paired_difference([a[s] for s in seeds], [b[s] for s in seeds])


def trained_timesteps(model: Path) -> int:
    """The environment steps (here fetches) a Stable-Baselines3 model was trained on, from
    the ``num_timesteps`` its zip records."""
    with zipfile.ZipFile(model) as z:
        return int(json.loads(z.read("data"))["num_timesteps"])


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run", type=Path, help="the folder scripts/train_agent.sh wrote")
    p.add_argument("--algo", choices=("ppo", "sac"), required=True)
    p.add_argument("--headroom", type=Path, default=HEADROOM)
    p.add_argument("--paired-with", type=Path, default=None, metavar="LOG",
                   help="the episode log (JSON Lines) of model-based on the same scenes: "
                   "stores the learned agent's paired difference to it")
    args = p.parse_args()
    heldout = json.loads((args.run / "heldout.json").read_text())
    config = yaml.safe_load((args.run / "config.yml").read_text())
    data = json.loads(args.headroom.read_text())
    env_id = heldout["env"]
    if env_id not in data["results"]:
        sys.exit(f"{args.headroom}: no headroom run of {env_id}")
    base = data["results"][env_id]
    seed = re.search(r"--seed (\d+)", base["command"])
    episodes = base["agents"]["study"]["episodes"]
    if (heldout["seed"], heldout["episodes"], heldout["env_kwargs"]) != (
            int(seed.group(1)) if seed else None, episodes, {}):
        sys.exit(f"{args.run}/heldout.json is not on the headroom scenes of {env_id} "
                 f"(seed {seed.group(1) if seed else '?'}, {episodes} episodes, default env)")
    (summary,) = heldout["agents"].values()
    base["agents"][args.algo] = summary
    wall = (args.run / "train_wall.txt").read_text().strip()
    base.setdefault("trained", {})[args.algo] = {
        "timesteps": trained_timesteps(args.run / "model.zip"),
        "timesteps_budget": config.get("timesteps") or config.get("hyperparams", {}).get(
            "n_timesteps"),
        "train_wall_s": int(wall), "command": config.get("command"),
        "versions": config.get("versions"), "machine": heldout.get("machine"),
        "script": f"scripts/train_agent.sh {env_id} {args.algo}"}
    if args.paired_with is not None:
        base["trained"][args.algo]["minus_model_based"] = _paired(
            args.run / "heldout.episodes.jsonl", args.paired_with)
    tmp = args.headroom.with_name(args.headroom.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1) + "\n")
    tmp.replace(args.headroom)
    print(f"{env_id} {args.algo}: {summary['reward_mean']:.3f} {summary['reward_ci95']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

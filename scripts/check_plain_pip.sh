#!/usr/bin/env bash
# What a user gets from plain pip, outside the Makefile: a fresh venv, `pip install ".[train]"` (no constraints
# file, nothing --no-deps), `pip check`, then from outside the source tree: check_env on both tasks with no
# display, make_vec of both tasks, a demonstration set collected and loaded with minari.load_dataset, and BC, IQL
# and PPO trained a few steps. Run by .ci/run after `make test`.
set -euo pipefail
SRC="$(cd "$(dirname "$0")/.." && pwd)"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
# The working tree's files (not the folder itself: building in place would leave build/ in it).
mkdir "$WORK/src"
(cd "$SRC" && git ls-files -z --cached --others --exclude-standard | xargs -0 tar --ignore-failed-read -cf - 2>/dev/null) \
    | tar -xf - -C "$WORK/src"
python3 -m venv "$WORK/venv"
PY="$WORK/venv/bin/python"
echo "plain pip: installing torch (CPU) and .[train] into a fresh venv"
quiet_pip() {  # pip's notes about the machine's unreachable local indexes are noise; its exit status is kept
    "$PY" -m pip install -q "$@" 2>&1 | { grep -v "is ignored" || true; }
    return "${PIPESTATUS[0]}"
}
quiet_pip torch==2.13.0
quiet_pip "$WORK/src[train]"
"$PY" -m pip check
cd "$WORK"
export MINARI_DATASETS_PATH="$WORK/minari" MPLBACKEND=Agg
unset DISPLAY WAYLAND_DISPLAY SDL_VIDEODRIVER
"$PY" - <<'PYEOF'
import gymnasium as gym
from gymnasium.utils.env_checker import check_env

import curbside  # registers the env ids

for task in ("PointNav", "SocialNav"):
    env = gym.make(f"curbside/{task}-v0")
    check_env(env.unwrapped)
    env.close()
    envs = gym.make_vec(f"curbside/{task}-v0", num_envs=2, config={"scene": {"blocks": 1}})
    envs.reset(seed=0)
    envs.step(envs.action_space.sample())
    envs.close()
    print(f"{task}: check_env passes headless; make_vec gives {type(envs).__name__}")
PYEOF
CS="$WORK/venv/bin/curbside"
CFG='{"scene": {"blocks": 1}, "route_length": [5.0, 25.0]}'
"$CS" demos collect --steps 300 --scenes 2 --config "$CFG"
"$PY" -c "import minari; ds = minari.load_dataset('curbside/pointnav-expert-v0'); print('minari.load_dataset:', ds.total_episodes, 'episodes')"
DEMOS="$MINARI_DATASETS_PATH/curbside/pointnav-expert-v0"
"$CS" train run --algo bc --demos "$DEMOS" --steps 50 --config "$CFG" --scenes 2 --out "$WORK/bc"
"$CS" train run --algo iql --demos "$DEMOS" --steps 50 --config "$CFG" --scenes 2 --out "$WORK/iql"
"$CS" train run --algo ppo --steps 256 --envs 2 --scenes 2 --config "$CFG" --out "$WORK/ppo"
"$CS" train eval "$WORK/iql" --episodes 1 --config "$CFG"
echo "plain pip: ok"

"""The catalog contract (docs/design.md): the simulator never imports torch, transformers or open_clip."""

from __future__ import annotations

import subprocess
import sys


def test_sim_imports_no_ml_frameworks() -> None:
    code = (
        "import sys, sim, sim.envs.pointnav, sim.envs.socialnav, sim.scene, sim.agents, catalogs.reader\n"
        "print(sorted(m for m in ('torch', 'transformers', 'open_clip', 'sentence_transformers') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd="/")
    assert out.stdout.strip().splitlines()[-1] == "[]"

"""A scene dataset's statistics beside MetaUrban-12K's (the paper's appendix), each measured as documented here.

| statistic | how curbside measures it |
|---|---|
| objects per scene | static objects in the spec (`objects`, building facades included) |
| static objects per m² | objects / scene area |
| mean nearest-object distance | per object, the gap between its footprint and the nearest other object's footprint; mean over objects |
| area occupied by objects | sum of object footprint areas (m²) |
| area per scene | area of the scene's bounding box (`bounds`) |
| dynamic agents per block | agents SocialNav's default crowd spawns (dynamic_density per 100 m of sidewalk) / blocks |
| mean route length | one PointNav route per scene drawn with `route_length` (the split's default unless given) |
| episodes over 800 steps | share of those routes the expert needs more than 800 steps for (length / 2.5 m/s / 0.1 s) |
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from sim.scene.scene import Scene, as_scene

# MetaUrban-12K (Wu et al., ICLR 2025, appendix): ">= 300" is a minimum, not a mean; the others are means.
PAPER_STATS: dict[str, tuple[float, str]] = {
    "objects_per_scene": (300.0, ">= 300 (minimum)"),
    "objects_per_m2": (0.03, "0.03"),
    "nearest_object_m": (0.7, "0.7 m"),
    "occupied_area_m2": (5250.0, "~5,250 m²"),
    "scene_area_m2": (20000.0, "~20,000 m²"),
    "agents_per_block": (10.0, "10"),
    "route_length_m": (410.0, "410 m"),
    "episodes_over_800_steps": (0.20, "> 20 %"),
}
LABELS = {
    "objects_per_scene": "objects per scene",
    "objects_per_m2": "static objects per m²",
    "nearest_object_m": "mean nearest-object distance (m)",
    "occupied_area_m2": "area occupied by objects (m²)",
    "scene_area_m2": "area per scene (m²)",
    "agents_per_block": "dynamic agents per block",
    "route_length_m": "mean PointNav route length (m)",
    "episodes_over_800_steps": "episodes over 800 steps",
}
LOWER_BOUNDS = ("objects_per_scene", "episodes_over_800_steps")  # ">= 300 per scene", "> 20 %"; the rest: within 25 %
EXPERT_SPEED = 2.5  # m/s: the built-in expert's cruise speed (sim.expert.PurePursuitExpert)


def scene_figures(
    spec: Scene | Mapping[str, Any],
    rng: np.random.Generator,
    route_length: tuple[float, float],
    agents: dict[str, Any] | None = None,
) -> dict[str, float]:
    """The per-scene figures of the table above for one scene (a dict is parsed)."""
    import shapely
    from shapely.geometry import Polygon

    from sim.agents.crowd import AGENT_DEFAULTS, sidewalk_length
    from sim.route import RouteError, RoutePlanner

    scene = as_scene(spec)
    objs = [o for o in scene.objects if len(o.get("footprint") or []) >= 3]
    polys = [Polygon(o["footprint"]) for o in objs]
    xmin, ymin, xmax, ymax = scene.bounds
    area = (xmax - xmin) * (ymax - ymin)
    gaps = []
    if len(polys) > 1:
        tree = shapely.STRtree(polys)
        for i, poly in enumerate(polys):
            # The nearest other footprint: query a growing window, then exact distances.
            for r in (2.0, 10.0, 50.0, 1e4):
                idx = [j for j in tree.query(poly.buffer(r)) if j != i]
                if idx:
                    gaps.append(min(poly.distance(polys[j]) for j in idx))
                    break
    blocks = max(len(scene.roads), 1)  # one road polygon per block
    density = float((agents or {}).get("dynamic_density", AGENT_DEFAULTS["dynamic_density"]))
    out = {
        "objects_per_scene": float(len(scene.objects)),
        "objects_per_m2": len(scene.objects) / area,
        "nearest_object_m": float(np.mean(gaps)) if gaps else float("nan"),
        "occupied_area_m2": float(sum(p.area for p in polys)),
        "scene_area_m2": area,
        "agents_per_block": round(density * sidewalk_length(scene) / 100.0) / blocks,
    }
    try:
        route = RoutePlanner(scene, 0.3).sample(rng, *route_length)
        out["route_length_m"] = route.length
    except RouteError:
        out["route_length_m"] = float("nan")
    out["episodes_over_800_steps"] = float(out["route_length_m"] / (EXPERT_SPEED * 0.1) > 800)
    return out


def dataset_vs_paper(
    directory: str | Path,
    *,
    route_length: tuple[float, float] | None = None,
    seed: int = 0,
    agent_density: float | None = None,
    progress: Callable[[int], None] | None = None,
) -> dict[str, Any]:
    """Mean of every figure over a dataset's scenes beside the paper's, with the ratio; also the per-scene values."""
    from sim.scene.dataset import read_index
    from sim.tasks.pointnav import DEFAULT_CONFIG
    from sim.tasks.scene_loader import read_scene

    d = Path(directory)
    rows = read_index(d)
    if not rows:
        raise ValueError(f"{d}/index.jsonl lists no scenes; regenerate the dataset with `curbside scenes dataset`")
    rl = tuple(route_length or DEFAULT_CONFIG["route_length"])
    rng = np.random.default_rng(seed)
    per_scene: dict[str, list[float]] = {k: [] for k in PAPER_STATS}
    for r in rows:
        figs = scene_figures(
            read_scene(d / r["file"]), rng, rl, None if agent_density is None else {"dynamic_density": agent_density}
        )
        for k, v in figs.items():
            per_scene[k].append(v)
        if progress:
            progress(1)
    table = {}
    for k, (paper, paper_text) in PAPER_STATS.items():
        ours = float(np.nanmean(per_scene[k]))
        if k in LOWER_BOUNDS:  # the paper gives a bound: every scene (objects) or the share (episodes) meets it
            value = float(np.nanmin(per_scene[k])) if k == "objects_per_scene" else ours
            meets = bool(value >= paper)
        else:
            meets = bool(abs(ours / paper - 1.0) <= 0.25)
        table[k] = {
            "ours": ours,
            "paper": paper,
            "paper_text": paper_text,
            "ratio": ours / paper,
            "meets": meets,
            "min": float(np.nanmin(per_scene[k])),
            "max": float(np.nanmax(per_scene[k])),
        }
    return {
        "scenes": len(rows),
        "route_length": list(rl),
        "agent_density": agent_density,
        "table": table,
        "per_scene": per_scene,
    }


def plot_vs_paper(result: dict[str, Any], png: Path) -> Path:
    """The paper's statistics figure for our data: histograms of object count, occupied area and episode length."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ps = result["per_scene"]
    steps = np.asarray(ps["route_length_m"], dtype=float) / (EXPERT_SPEED * 0.1)
    panels = (
        ("objects_per_scene", np.asarray(ps["objects_per_scene"]), "objects per scene", 300.0),
        ("occupied_area_m2", np.asarray(ps["occupied_area_m2"]), "area occupied by objects (m²)", 5250.0),
        ("episode_steps", steps[np.isfinite(steps)], "episode length (expert steps)", 410.0 / (EXPERT_SPEED * 0.1)),
    )
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for ax, (_, values, label, paper) in zip(axes, panels):
        ax.hist(values, bins=min(30, max(5, len(values) // 3)), color="#1565c0", alpha=0.85)
        ax.axvline(
            float(np.mean(values)) if len(values) else 0.0,
            color="#e65100",
            lw=1.2,
            label=f"curbside mean {np.mean(values) if len(values) else float('nan'):.0f}",
        )
        ax.axvline(paper, color="#424242", lw=1.2, ls="--", label=f"MetaUrban-12K {paper:.0f}")
        ax.set_xlabel(label)
        ax.set_ylabel("scenes")
        ax.legend(fontsize=8)
    fig.suptitle(f"{result['scenes']} scenes vs MetaUrban-12K", fontsize=10)
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    plt.close(fig)
    return png


def write_vs_paper(result: dict[str, Any], directory: Path) -> tuple[Path, Path]:
    """stats_vs_paper.json (table and per-scene values) and stats_vs_paper.png in the dataset folder."""
    js = directory / "stats_vs_paper.json"
    js.write_text(json.dumps(result, indent=1, sort_keys=True, default=float), encoding="utf-8")
    return js, plot_vs_paper(result, directory / "stats_vs_paper.png")

"""Top-down matplotlib rendering of a scene spec: roads, lane lines, zones, crosswalks, objects, scale bar."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from sim.palette import OBJECT_CLASS, SURFACE, ZONE


def render_scene(spec: dict[str, Any], out: str | Path, *, dpi: int = 150, title: str | None = None) -> Path:
    """Draw `spec` top-down to a PNG at `out` and return its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.patches import Patch, Rectangle

    xmin, ymin, xmax, ymax = spec["bounds"]
    w, h = xmax - xmin, ymax - ymin
    scale = 12.0 / max(w, h)
    fig, ax = plt.subplots(figsize=(max(w * scale, 4) + 2.5, max(h * scale, 4)))
    ax.set_facecolor(SURFACE["ground"][:3])
    ax.add_collection(PolyCollection([r["polygon"] for r in spec["roads"]], facecolors=[SURFACE["road"][:3]], edgecolors="none"))
    islands = [r["island"] for r in spec["roads"] if r.get("island")]
    if islands:
        ax.add_collection(PolyCollection(islands, facecolors="#81c784", edgecolors="#33691e", linewidths=0.5))
    lines = [ln for r in spec["roads"] for ln in r["lane_lines"]]
    ax.add_collection(LineCollection(lines, colors="white", linewidths=0.6, linestyles=(0, (4, 3))))
    for kind, color in ZONE.items():
        polys = [z["polygon"] for s in spec["sidewalks"] for z in s["zones"] if z["kind"] == kind]
        if polys:
            ax.add_collection(PolyCollection(polys, facecolors=color, edgecolors="#9e9e9e", linewidths=0.2))
    ax.add_collection(LineCollection([s["edge"] for s in spec["sidewalks"]], colors="#424242", linewidths=0.8))
    ax.add_collection(LineCollection([s["clear_path"] for s in spec["sidewalks"]], colors="#90a4ae", linewidths=0.4, linestyles=":"))
    cws = [c["polygon"] for c in spec["crosswalks"]]
    ax.add_collection(PolyCollection(cws, facecolors="white", edgecolors="#212121", linewidths=0.5, hatch="||||"))
    ramps = [r["polygon"] for c in spec["crosswalks"] for r in c["ramps"]]
    ax.add_collection(PolyCollection(ramps, facecolors=[SURFACE["ramp"][:3]], edgecolors="#f9a825", linewidths=0.4))
    for cls, color in OBJECT_CLASS.items():
        if cls == "building":
            polys = [o["footprint"] for o in spec["objects"] if o["category"] == "building_facade"]
        else:
            polys = [o["footprint"] for o in spec["objects"] if o["object_class"] == cls and o["category"] != "building_facade"]
        if polys:
            ax.add_collection(PolyCollection(polys, facecolors=color, edgecolors="black", linewidths=0.2,
                                             alpha=0.55 if cls == "building" else 0.95))
    bar = 10.0 if max(w, h) < 150 else 50.0
    x0, y0 = xmin + 0.03 * w, ymin + 0.03 * h
    ax.add_patch(Rectangle((x0, y0), bar, max(h, w) * 0.006, color="black"))
    ax.text(x0 + bar / 2, y0 + max(h, w) * 0.015, f"{bar:.0f} m", ha="center", va="bottom", fontsize=8)
    handles = [Patch(color=SURFACE["road"][:3], label="road")] + [Patch(color=c, label=k.replace("_", " ")) for k, c in ZONE.items()]
    handles += [Patch(facecolor="white", edgecolor="black", hatch="||||", label="crosswalk"), Patch(color=SURFACE["ramp"][:3], label="curb ramp")]
    handles += [Patch(color=c, label=f"{k.replace('_', '-')} object" if k != "building" else "building facade")
                for k, c in OBJECT_CLASS.items()]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False)
    ax.set_xlim(xmin - 2, xmax + 2)
    ax.set_ylim(ymin - 2, ymax + 2)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    st = spec.get("stats", {})
    ax.set_title(title or f"seed {spec['seed']} · blocks {st.get('blocks', '')} · {st.get('objects', 0)} objects", fontsize=9)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return out

"""Retrieval quality per scorer: category accuracy and precision@k on held-out procedural variants (seeds 0-1, never
trained on) and on the primitive mesh set (hand-built, not procedural), 33 category prompts as the pool.

Run: HF_HUB_OFFLINE=1 python benchmarks/retrieval_eval.py   (about 6 minutes on 2 cores)
Writes benchmarks/results/retrieval/retrieval_eval.{json,md}.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

OUT = Path(__file__).parent / "results" / "retrieval"
SCORERS = {  # name -> ScoringConfig fields
    "aligned (one global threshold, default)": {"image_encoder": "aligned"},
    "aligned (calibrated thresholds)": {"image_encoder": "aligned", "thresholds": "calibrated"},
    "imagenet": {"image_encoder": "imagenet"},
    "text only (noisy names)": {"image_encoder": "none"},
}


def main() -> None:
    """Evaluate every scorer on both sets; print a markdown table and save it with the JSON."""
    from rich.progress import track

    from retrieval.evaluation import evaluate
    from retrieval.ingest import IngestConfig
    from retrieval.primitive_set import build_set
    from retrieval.scoring import ScoringConfig
    from retrieval.sources import open_source

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        build_set(Path(tmp) / "primitives")
        jobs = [
            (name, fields, mesh_set) for name, fields in SCORERS.items() for mesh_set in ("procedural", "primitives")
        ]
        for name, fields, mesh_set in track(jobs, description="evaluating"):
            src = (
                open_source("procedural", per_category=2, work_dir=Path(tmp) / "proc")
                if mesh_set == "procedural"
                else open_source(f"local:{Path(tmp) / 'primitives'}")
            )
            rep = evaluate(src, IngestConfig(scoring=ScoringConfig(**fields)))
            rows.append(
                {
                    "scorer": name,
                    "set": mesh_set,
                    "assets": rep.n_assets,
                    "category_accuracy": round(rep.category_accuracy, 3),
                    **{f"P@{k}": round(v, 3) for k, v in rep.precision_at_k.items()},
                }
            )
            print(rows[-1], flush=True)
    lines = ["| scorer | set | assets | category accuracy | P@1 | P@5 |", "|---|---|---|---|---|---|"]
    lines += [
        f"| {r['scorer']} | {r['set']} | {r['assets']} | {r['category_accuracy']:.3f} | {r['P@1']:.3f} | "
        f"{r['P@5']:.3f} |"
        for r in rows
    ]
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "retrieval_eval.md").write_text(
        "`HF_HUB_OFFLINE=1 python benchmarks/retrieval_eval.py` (20 views at 160 px, "
        "3 scored; 33 category prompts)\n\n" + "\n".join(lines) + "\n"
    )
    (OUT / "retrieval_eval.json").write_text(json.dumps(rows, indent=2) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()

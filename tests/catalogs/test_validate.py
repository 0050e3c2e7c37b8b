"""validate_catalog: good meshes pass; missing, corrupt, mis-sized and misplaced meshes are reported by id."""

from __future__ import annotations

from pathlib import Path

import trimesh

from catalogs.layout import asset_root
from catalogs.validate import validate_catalog
from catalogs.writer import build_catalog


def _box(path: Path, size: tuple[float, float, float], lift: float = 0.0) -> str:
    mesh = trimesh.creation.box(size)
    mesh.apply_translation([0, 0, size[2] / 2 + lift])
    path.parent.mkdir(parents=True, exist_ok=True)
    mesh.export(path)
    return path.relative_to(path.parents[3]).as_posix()  # relative to the catalog directory


def test_validate_reports_each_bad_asset_with_reason(tmp_path: Path, make_asset, random_unit_vectors) -> None:
    cat = tmp_path / "c.duckdb"
    root = asset_root(cat)
    size = (0.6, 1.8, 0.85)
    good = _box(root / "good" / "m" / "model.obj", size)
    off = _box(root / "off" / "m" / "model.obj", (0.6, 1.8, 1.0))
    lifted = _box(root / "lifted" / "m" / "model.obj", size, lift=0.5)
    corrupt = root / "corrupt" / "m" / "model.obj"
    corrupt.parent.mkdir(parents=True)
    corrupt.write_text("this is not an OBJ file\n")
    records = [
        make_asset("good", mesh_path=good),
        make_asset("missing", mesh_path="c_assets/missing/model.obj"),
        make_asset("corrupt", mesh_path=corrupt.relative_to(tmp_path).as_posix()),
        make_asset("off", mesh_path=off),
        make_asset("lifted", mesh_path=lifted),
        make_asset("noglb", mesh_path=good, glb_path="c_assets/none.glb"),
        make_asset("noemb", mesh_path=good),
    ]
    ids = [r.asset_id for r in records if r.asset_id != "noemb"]
    with build_catalog(cat) as w:
        w.upsert_assets(records)
        w.upsert_embeddings("asset_text", ids, random_unit_vectors(len(ids)))
    n, problems = validate_catalog(cat, progress=False)
    assert n == len(records)
    by_id: dict[str, list[str]] = {}
    for p in problems:
        by_id.setdefault(p.asset_id, []).append(p.reason)
    assert "good" not in by_id, by_id.get("good")
    assert set(by_id) == {"missing", "corrupt", "off", "lifted", "noglb", "noemb"}
    assert "mesh file missing" in by_id["missing"][0]
    assert any("does not load" in r for r in by_id["corrupt"])
    assert any("differs from the recorded" in r and "2%" in r for r in by_id["off"])
    assert any("base is at z = 0.500" in r for r in by_id["lifted"])
    assert any("glb file missing" in r for r in by_id["noglb"])
    assert any("no asset_text embedding" in r for r in by_id["noemb"])


def test_validate_reports_missing_catalog(tmp_path: Path) -> None:
    n, problems = validate_catalog(tmp_path / "none.duckdb", progress=False)
    assert n == 0 and problems[0].asset_id is None and "curbside catalog build" in problems[0].reason

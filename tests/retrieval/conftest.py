"""Fixtures of the retrieval tests: a local folder of good and bad meshes, built with trimesh."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh


def bench_mesh() -> trimesh.Trimesh:
    """A small coloured bench (seat, back, four legs), z-up metres."""
    seat = trimesh.creation.box([0.6, 1.8, 0.1])
    seat.apply_translation([0, 0, 0.45])
    seat.visual.face_colors = [150, 90, 40, 255]
    back = trimesh.creation.box([0.08, 1.8, 0.5])
    back.apply_translation([-0.28, 0, 0.75])
    back.visual.face_colors = [20, 120, 40, 255]
    legs = []
    for x, y in [(-0.25, -0.8), (0.25, -0.8), (-0.25, 0.8), (0.25, 0.8)]:
        leg = trimesh.creation.box([0.08, 0.08, 0.45])
        leg.apply_translation([x, y, 0.225])
        leg.visual.face_colors = [40, 40, 40, 255]
        legs.append(leg)
    return trimesh.util.concatenate([seat, back, *legs])


def cone_mesh() -> trimesh.Trimesh:
    """An orange traffic cone in centimetres (a unit the size normalisation must detect)."""
    cone = trimesh.creation.cone(radius=15.0, height=70.0, sections=24)
    cone.visual.face_colors = [240, 110, 20, 255]
    return cone


@pytest.fixture(scope="session")
def mesh_folder(tmp_path_factory) -> dict:
    """Folder with two good meshes and one file for each kind of bad input; returns paths and expected reasons."""
    root = tmp_path_factory.mktemp("meshes")
    bench_mesh().export(root / "a_bench.ply")
    (root / "a_bench.ply.json").write_text('{"name": "park bench", "license": "CC0-1.0", "attribution": "test"}')
    # GLB is y-up: rotate the z-up cone so the loader's y-up convention brings it back upright.
    cone = cone_mesh()
    cone.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    trimesh.Scene([cone]).export(root / "b_cone.glb")
    (root / "b_cone.json").write_text('{"name": "orange traffic cone", "category": "traffic_cone"}')
    (root / "c_corrupt.glb").write_bytes(b"glTF\x02\x00\x00\x00garbage" * 10)
    (root / "d_empty.obj").write_text("# nothing\nv 0 0 0\nv 1 0 0\n")
    nan = trimesh.creation.box([1, 1, 1])
    verts = nan.vertices.copy()
    verts[0] = np.nan
    (root / "e_nan.obj").write_text(
        "\n".join([f"v {x} {y} {z}" for x, y, z in verts] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in nan.faces])
        + "\n"
    )
    trimesh.creation.icosphere(subdivisions=5).export(root / "f_many_faces.stl")  # 20480 faces > test limit
    (root / "g_missing_tex.obj").write_text("mtllib g.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 1\nf 1 2 3\n")
    (root / "g.mtl").write_text("newmtl m\nmap_Kd nowhere.png\n")
    plane = trimesh.creation.box([1.0, 1.0, 0.0])
    plane.export(root / "h_thin.stl")
    return {
        "root": root,
        "good": ["a_bench.ply", "b_cone.glb"],
        "reasons": {
            "c_corrupt.glb": "corrupt_file",
            "d_empty.obj": "empty_mesh",
            "e_nan.obj": "nan_vertices",
            "f_many_faces.stl": "too_many_faces",
            "g_missing_tex.obj": "missing_texture",
            "h_thin.stl": "degenerate",
        },
    }


def ingest_two_procedural(scoring, tmp_path):  # noqa: ANN001, ANN201 - (IngestReport, catalog path)
    """Ingest two procedural assets (4 views, 2 scored) with `scoring` into a fresh catalog under `tmp_path`."""
    from retrieval.ingest import IngestConfig, ingest
    from retrieval.sources.procedural import ProceduralSource

    cat = tmp_path / "c.duckdb"
    report = ingest(
        ProceduralSource(per_category=1, work_dir=tmp_path / "proc"),
        cat,
        IngestConfig(n_views=4, n_informative=2, scoring=scoring),
        limit=2,
        progress=False,
    )
    return report, cat

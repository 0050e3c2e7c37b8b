"""Catalog validation: schema version, files exist, meshes load (trimesh and PyBullet), dimensions match, embeddings.

trimesh and pybullet are imported inside `validate_catalog`, so importing this module stays cheap.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from catalogs.reader import CatalogReader
from catalogs.records import AssetRecord
from catalogs.schema import CatalogError, CatalogLocked

DIM_TOLERANCE = 0.02  # recorded extents must match the mesh bounding box within 2 %
ABS_TOLERANCE = 1e-3  # metres; keeps millimetre-thin parts (sign plates) from failing on rounding alone


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a catalog: the asset (None for the catalog itself) and the reason."""

    asset_id: str | None
    reason: str

    def to_dict(self) -> dict:
        """The problem as a JSON-ready dict."""
        return asdict(self)


@contextlib.contextmanager
def _stdout_to_stderr() -> Iterator[None]:
    """Send C-level stdout (PyBullet's b3Warning lines) to stderr so machine-readable stdout stays clean."""
    sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no real stdout (e.g. a test runner's capture): nothing to protect
        yield
        return
    try:
        os.dup2(2, 1)
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


def _dims_problem(what: str, recorded: tuple[float, float, float], extents: np.ndarray) -> str | None:
    """A reason string when `extents` differ from the recorded depth/width/height by more than the tolerance."""
    rec = np.asarray(recorded, dtype=np.float64)
    ext = np.asarray(extents, dtype=np.float64)
    off = np.abs(ext - rec) > np.maximum(DIM_TOLERANCE * rec, ABS_TOLERANCE)
    if not off.any():
        return None
    shown = " x ".join(f"{v:.3f}" for v in ext)
    return (
        f"{what} bounding box {shown} m differs from the recorded depth x width x height "
        f"{' x '.join(f'{v:.3f}' for v in rec)} m by more than {DIM_TOLERANCE:.0%}"
    )


def check_asset_files(reader: CatalogReader, rec: AssetRecord, client: int) -> list[Problem]:
    """Problems of one asset's files: existence, trimesh and PyBullet loading, dimensions, placement."""
    from kernel.quiet import import_pybullet

    p = import_pybullet()
    import trimesh

    out: list[Problem] = []
    if rec.mesh_path is None:
        return [Problem(rec.asset_id, "no mesh_path recorded")]
    for label, rel in (("mesh", rec.mesh_path), ("glb", rec.glb_path), ("collision mesh", rec.collision_path)):
        f = reader.resolve(rel)
        if f is not None and not f.is_file():
            out.append(Problem(rec.asset_id, f"{label} file missing: {f}"))
    mesh_file = reader.resolve(rec.mesh_path)
    if mesh_file is None or not mesh_file.is_file():
        return out
    try:
        mesh = trimesh.load(str(mesh_file), force="mesh")
        if mesh.is_empty or len(getattr(mesh, "faces", ())) == 0:
            raise ValueError("the file holds no faces")
    except Exception as e:  # noqa: BLE001 - any parser failure means the same thing: the mesh is corrupt
        out.append(Problem(rec.asset_id, f"mesh does not load in trimesh ({type(e).__name__}: {e}): {mesh_file}"))
        return out
    reason = _dims_problem("mesh", rec.size, mesh.extents)
    if reason:
        out.append(Problem(rec.asset_id, reason))
    lo, hi = mesh.bounds
    centre_off = np.abs((lo[:2] + hi[:2]) / 2)
    if lo[2] < -max(DIM_TOLERANCE * rec.height, ABS_TOLERANCE) or lo[2] > max(
        DIM_TOLERANCE * rec.height, ABS_TOLERANCE
    ):
        out.append(Problem(rec.asset_id, f"mesh base is at z = {lo[2]:.3f} m; the convention is base at z = 0"))
    if (centre_off > np.maximum(DIM_TOLERANCE * np.asarray(rec.size[:2]), ABS_TOLERANCE)).any():
        out.append(
            Problem(rec.asset_id, f"mesh is not centred on the x/y origin (centre off by {centre_off.round(3)} m)")
        )
    try:
        with _stdout_to_stderr():
            shape = p.createCollisionShape(p.GEOM_MESH, fileName=str(mesh_file), physicsClientId=client)
            body = p.createMultiBody(0, shape, physicsClientId=client)
            n, verts = p.getMeshData(body, physicsClientId=client)
            p.removeBody(body, physicsClientId=client)
        if n == 0:
            raise ValueError("no vertices")
        verts = np.asarray(verts, dtype=np.float64)
        reason = _dims_problem("PyBullet mesh", rec.size, verts.max(axis=0) - verts.min(axis=0))
        if reason:
            out.append(Problem(rec.asset_id, reason))
    except Exception as e:  # noqa: BLE001 - pybullet.error carries no detail beyond its message
        out.append(Problem(rec.asset_id, f"mesh does not load in PyBullet ({e}): {mesh_file}"))
    return out


def check_embeddings(path: str | Path, reader: CatalogReader) -> list[Problem]:
    """Problems of the text embeddings: assets without one, vectors that are not unit length."""
    from catalogs.reader import catalog_errors, open_catalog

    con = open_catalog(path)
    try:
        with catalog_errors(path):  # a damaged embeddings block shows only here
            rows = con.execute(
                "SELECT a.asset_id, e.owner_id IS NULL, coalesce(sqrt(array_inner_product(e.vector, e.vector)), 0)"
                " FROM assets a LEFT JOIN embeddings e ON e.owner_id = a.asset_id AND e.owner_kind = 'asset_text'"
                " AND e.model = $model ORDER BY a.asset_id",
                {"model": reader.meta.get("embedding_model")},
            ).fetchall()
    finally:
        con.close()
    out = []
    for asset_id, missing, norm in rows:
        if missing:
            out.append(Problem(asset_id, "no asset_text embedding; `curbside catalog query` cannot find it"))
        elif abs(norm - 1.0) > 1e-3:
            out.append(Problem(asset_id, f"asset_text embedding has norm {norm:.4f}, expected a unit vector"))
    return out


def validate_catalog(path: str | Path, *, progress: bool = True) -> tuple[int, list[Problem]]:
    """Check a catalog end to end; returns (number of assets checked, problems found)."""
    from kernel.quiet import import_pybullet

    p = import_pybullet()
    from rich.console import Console
    from rich.progress import Progress

    try:
        reader = CatalogReader(path)
    except CatalogLocked:
        raise  # not a defect of the catalog: the caller says "wait and retry"
    except CatalogError as e:  # corrupt, not a catalog, other schema version: the report says which
        return 0, [Problem(None, str(e))]
    problems: list[Problem] = []
    with _stdout_to_stderr():
        client = p.connect(p.DIRECT)
    try:
        with Progress(console=Console(stderr=True), disable=not progress, transient=True) as bar:
            task = bar.add_task("validating assets", total=len(reader))
            for asset_id in reader.table.asset_id:
                problems += check_asset_files(reader, reader.get(str(asset_id)), client)
                bar.advance(task)
    finally:
        p.disconnect(client)
    try:
        problems += check_embeddings(path, reader)
    except CatalogLocked:
        raise
    except CatalogError as e:
        problems.append(Problem(None, str(e)))
    return len(reader), problems

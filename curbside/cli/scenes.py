"""`curbside scenes`: Generate, render and collect urban scenes (scene specs as JSON)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

app = typer.Typer(help="Generate, render and collect urban scenes (scene specs as JSON).", no_args_is_help=True)

DEFAULT_CATALOG = Path("catalogs/default.duckdb")


def _catalog(path: Path | None) -> str | None:
    """The catalog to use: the given path, else catalogs/default.duckdb when present, else none (fallback boxes)."""
    if path is not None:
        if not path.exists():
            raise typer.BadParameter(f"no catalog at {path}; build one with `curbside catalog build`", param_hint="--catalog")
        return str(path)
    if DEFAULT_CATALOG.exists():
        return str(DEFAULT_CATALOG)
    typer.secho(
        f"warning: no catalog given and {DEFAULT_CATALOG} does not exist; objects are default-size boxes "
        "(build a catalog with `curbside catalog build`)", fg="yellow", err=True,
    )
    return None


def _blocks(value: str) -> int | str:
    return int(value) if value.isdigit() else value


def _fail(e: Exception) -> None:
    typer.secho(f"error: {e}", fg="red", err=True)
    raise typer.Exit(2)


@app.command()
def generate(
    out: Path = typer.Option(..., "--out", "-o", help="Scene spec JSON to write."),
    blocks: str = typer.Option("3", help="Number of blocks, or block codes such as SXC (S, C, X, T, O)."),
    seed: int = typer.Option(0, help="Random seed."),
    templates: str = typer.Option("abcdef", help="Sidewalk templates to draw from (a-g)."),
    object_density: float = typer.Option(1.0, "--object-density", help="Object density rho_s."),
    country: str | None = typer.Option(None, help="ISO country code of the category distribution (default: uniform)."),
    catalog: Path | None = typer.Option(None, help="Asset catalog (default: catalogs/default.duckdb if present)."),
    crosswalk_density: float = typer.Option(0.5, "--crosswalk-density", help="Fraction of crosswalk candidates built."),
) -> None:
    """Generate one scene spec."""
    import warnings

    from curbside.config import ConfigError
    from catalogs.schema import CatalogError
    from sim.scene import generate_scene, save

    cfg = {"blocks": _blocks(blocks), "templates": templates, "object_density": object_density,
           "country": country, "crosswalk_density": crosswalk_density}
    cat = _catalog(catalog)
    try:
        with warnings.catch_warnings(record=True):
            warnings.simplefilter("always")
            spec = generate_scene(cfg, seed, cat)
    except (ConfigError, CatalogError) as e:
        _fail(e)
    save(spec, out)
    st = spec["stats"]
    if st["fallback_categories"]:
        typer.secho(f"warning: default-size boxes for {', '.join(st['fallback_categories'])} (not in the catalog)", fg="yellow", err=True)
    typer.echo(f"{out}: blocks {st['blocks']}, {st['sidewalks']} sidewalks, {st['crosswalks']} crosswalks, "
               f"{st['objects']} objects ({st['refused_total']} refused), route {st['route_length_m']:.0f} m")


@app.command()
def render(
    scene: Path = typer.Argument(..., help="Scene spec JSON."),
    out: Path = typer.Option(..., "--out", "-o", help="PNG to write."),
    dpi: int = typer.Option(150, help="Resolution."),
) -> None:
    """Render a scene spec top-down to PNG."""
    from sim.scene import load
    from sim.scene.render import render_scene

    try:
        spec = load(scene)
    except (FileNotFoundError, ValueError) as e:
        _fail(e)
    typer.echo(str(render_scene(spec, out, dpi=dpi)))


@app.command()
def dataset(
    out: Path = typer.Option(..., "--out", "-o", help="Output folder (scenes/*.json, index.jsonl, index.parquet)."),
    split: str = typer.Option("train", help="train | test (templates a-f) | unseen | finetune (template g, held-out categories)."),
    count: int = typer.Option(100, help="Number of scenes."),
    blocks: str = typer.Option("3", help="Blocks per scene (count or codes)."),
    object_density: float = typer.Option(1.0, "--object-density", help="Object density rho_s."),
    catalog: Path | None = typer.Option(None, help="Asset catalog (default: catalogs/default.duckdb if present)."),
    workers: int = typer.Option(1, help="Worker processes."),
    preset: Optional[str] = typer.Option(None, help="Scene preset, e.g. metaurban12k (the paper's density)."),
) -> None:
    """Generate a MetaUrban-12K-style split: one JSON per scene plus an index of per-scene summaries."""
    import time

    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from curbside.config import ConfigError
    from sim.scene.dataset import build_dataset

    cat = _catalog(catalog)
    t0 = time.perf_counter()
    cols = (TextColumn(f"[bold]{split}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(), TimeRemainingColumn())
    try:
        with Progress(*cols) as bar:
            task = bar.add_task(split, total=count)
            base = {"blocks": _blocks(blocks), "object_density": object_density, **({"preset": preset} if preset else {})}
            rows = build_dataset(split, count, out, base=base,
                                 catalog=cat, workers=workers, progress=lambda n: bar.advance(task, n))
    except ConfigError as e:
        _fail(e)
    dt = time.perf_counter() - t0
    objs = sum(r["objects"] for r in rows)
    typer.echo(f"{out}: {len(rows)} scenes, {objs} objects, {dt:.1f} s ({len(rows) / dt:.1f} scenes/s)")


@app.command()
def stats(
    directory: Path = typer.Argument(..., help="Dataset folder written by `curbside scenes dataset`."),
    vs_paper: bool = typer.Option(False, "--vs-paper", help="Print each MetaUrban-12K statistic beside ours (+ PNG)."),
    route_preset: str = typer.Option("metaurban12k", help="Routes and agent density for --vs-paper: short (the "
                                     "default tasks) or metaurban12k (the paper-scale preset)."),
    seed: int = typer.Option(0, min=0, help="Seed of the route draws (--vs-paper)."),
) -> None:
    """Write a dataset's statistics (objects per scene, object area, route length) as PNG and JSON."""
    from sim.scene.dataset import dataset_stats

    try:
        st, png, js = dataset_stats(directory)
    except (FileNotFoundError, ValueError) as e:
        _fail(e)
    typer.echo(f"{st['scenes']} scenes: objects {st['objects']['mean']:.1f}±{st['objects']['std']:.1f}, "
               f"object area {st['object_area_m2']['mean']:.1f} m², route {st['route_length_m']['mean']:.0f} m")
    typer.echo(f"{png}\n{js}")
    if not vs_paper:
        return
    from rich.console import Console
    from rich.progress import track
    from rich.table import Table

    from sim.scene.paper_stats import LABELS, dataset_vs_paper, write_vs_paper

    bar = iter(track(range(st["scenes"]), description="scenes vs paper", transient=True))
    from sim.tasks.pointnav import ROUTE_LENGTHS

    if route_preset not in ROUTE_LENGTHS:
        _fail(ValueError(f"unknown --route-preset {route_preset!r}; valid: {', '.join(ROUTE_LENGTHS)}"))
    from sim.envs.socialnav import PRESETS as SOCIALNAV_PRESETS

    density = SOCIALNAV_PRESETS.get(route_preset, {}).get("agents", {}).get("dynamic_density")
    result = dataset_vs_paper(directory, seed=seed, route_length=tuple(ROUTE_LENGTHS[route_preset]),
                              agent_density=density, progress=lambda n: next(bar, None))
    table = Table(title=f"{result['scenes']} scenes vs MetaUrban-12K (routes drawn in {result['route_length']} m); "
                        "meets: within 25 % of the paper's mean, or its bound for >= and >")
    for col in ("statistic", "curbside (min-max)", "paper", "ratio", "meets"):
        table.add_column(col, justify="left" if col == "statistic" else "right")
    for k, row in result["table"].items():
        table.add_row(LABELS[k], f"{row['ours']:.3g} ({row['min']:.3g}-{row['max']:.3g})", row["paper_text"],
                      f"{row['ratio']:.2f}", "yes" if row["meets"] else "no")
    Console(width=max(Console().width, 110)).print(table)
    js2, png2 = write_vs_paper(result, directory)
    typer.echo(f"{png2}\n{js2}")

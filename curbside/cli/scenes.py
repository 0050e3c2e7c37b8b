"""`curbside scenes`: Generate, render and collect urban scenes (scene specs as JSON)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from enum import Enum
from pathlib import Path
from typing import Any

import typer

from catalogs import DEFAULT_CATALOG  # light: only the schema constants
from curbside.cli.errors import UsageError
from curbside.cli.executor_options import (
    EXECUTOR_HELP,
    Executor,
    address_option,
    check_executor_args,
    workers_option,
)
from sim.scene.config import DEFAULT_CONFIG  # the generator's defaults, which the options show (no pybullet)

app = typer.Typer(
    rich_markup_mode=None, help="Generate, render and collect urban scenes (scene specs as JSON).", no_args_is_help=True
)


def _terrain_density_option() -> Any:
    """The --terrain-density option of `generate` and `dataset`."""
    return typer.Option(
        DEFAULT_CONFIG["terrain"]["density"],
        "--terrain-density",
        help="Terrain patches (tree-root heave, uneven pavers, entrance "
        "steps, wet ground): 1 a city's typical share, 0 none, at most 10 (docs/terrain.md).",
    )


# Choices as Enums so `--help` lists them and a typo fails before any work (names kept in sync by tests).
Split = Enum("Split", {"train": "train", "test": "test", "unseen": "unseen", "finetune": "finetune"}, type=str)
# The scene presets (sim.scene.config.PRESETS, kept equal by a test) plus "none", the generator's plain defaults.
Preset = Enum("Preset", {"metaurban12k": "metaurban12k", "none": "none"}, type=str)
RoutePreset = Enum("RoutePreset", {"short": "short", "metaurban12k": "metaurban12k"}, type=str)
MAX_SEED = 2**32 - 1
MAX_COUNT = 1_000_000  # splits start 1,000,000 seeds apart (sim.scene.dataset.MAX_COUNT)


def _catalog(path: Path | None) -> str | None:
    """The catalog to use: the given path, else DEFAULT_CATALOG when present, else none (fallback boxes)."""
    if path is not None:
        if not path.exists():
            raise UsageError(f"no catalog at {path}; build one with `curbside catalog build` or leave out --catalog")
        return str(path)
    if Path(DEFAULT_CATALOG).exists():
        return DEFAULT_CATALOG
    typer.secho(
        f"warning: no catalog given and {DEFAULT_CATALOG} does not exist; objects are default-size boxes "
        "(build a catalog with `curbside catalog build`)",
        fg="yellow",
        err=True,
    )
    return None


def _blocks(value: str) -> int | str:
    return int(value) if value.strip().isdigit() else value


@contextmanager
def _catalog_errors() -> Iterator[None]:
    """A catalog the user named that is corrupt or of another schema is bad input (exit 2), not a failed run."""
    from catalogs.schema import CatalogError

    try:
        yield
    except CatalogError as e:
        raise UsageError(str(e)) from e


def _file_out(out: Path, example: str) -> None:
    """UsageError unless `out` can be a file (not an existing folder)."""
    if out.is_dir():
        raise UsageError(f"--out {out} is a directory; give a file path such as {out / example}")


@app.command()
def generate(
    out: Path = typer.Option(..., "--out", "-o", help="Scene spec JSON to write."),
    blocks: str = typer.Option(
        str(DEFAULT_CONFIG["blocks"]), help="Number of blocks (1-64), or block codes such as SXC (S, C, X, T, O)."
    ),
    seed: int = typer.Option(0, min=0, max=MAX_SEED, help="Random seed."),
    templates: str = typer.Option(DEFAULT_CONFIG["templates"], help="Sidewalk templates to draw from (a-g)."),
    object_density: float = typer.Option(
        DEFAULT_CONFIG["object_density"], "--object-density", help="Object density rho_s, a finite number in [0, 50]."
    ),
    country: str | None = typer.Option(
        DEFAULT_CONFIG["country"], help="ISO country code of the category distribution (default: uniform)."
    ),
    catalog: Path | None = typer.Option(None, help=f"Asset catalog (default: {DEFAULT_CATALOG} if present)."),
    crosswalk_density: float = typer.Option(
        DEFAULT_CONFIG["crosswalk_density"],
        "--crosswalk-density",
        help="Fraction of crosswalk candidates built, in [0, 1].",
    ),
    terrain_density: float = _terrain_density_option(),
    from_file: Path | None = typer.Option(
        None,
        "--from",
        exists=True,
        dir_okay=False,
        readable=True,
        help="A custom scene YAML (blocks, templates, object pool and density, "
        "named objects, agent groups; docs/scenes.md) instead of the options.",
    ),
) -> None:
    """Generate one scene spec."""
    import warnings

    from sim.scene import generate_scene, save
    from sim.scene.config import resolve_config

    _file_out(out, "scene.json")
    if from_file is not None:
        given = [
            name
            for name, value, default in (
                ("--blocks", blocks, "3"),
                ("--seed", seed, 0),
                ("--templates", templates, "abcdef"),
                ("--object-density", object_density, 1.0),
                ("--country", country, None),
            )
            if value != default
        ]
        if given:
            raise UsageError(
                f"--from takes the scene's settings from its file; drop {', '.join(given)} (or set them "
                "in the file: blocks, templates, seed, objects.density, objects.country)"
            )
        from sim.scene.custom import generate_custom, generator_config, load_custom

        custom = load_custom(from_file)
        resolve_config(generator_config(custom))  # a bad generator value fails before any work
        with _catalog_errors(), warnings.catch_warnings(record=True):
            warnings.simplefilter("always")
            spec = generate_custom(custom, _catalog(catalog))
        save(spec, out)
        agents = sum(spec.get("agents", {}).values())
        typer.echo(
            f"{out}: blocks {spec['stats']['blocks']}, {len(spec['objects'])} objects "
            f"({len(custom['place'])} named), {agents} agents in groups"
        )
        return
    cfg = {
        "blocks": _blocks(blocks),
        "templates": templates,
        "object_density": object_density,
        "country": country,
        "crosswalk_density": crosswalk_density,
        "terrain": {"density": terrain_density},
    }
    resolve_config(cfg)  # a bad value (NaN, out of range) fails here, before the catalog warning or any work
    cat = _catalog(catalog)
    with _catalog_errors(), warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        spec = generate_scene(cfg, seed, cat)
    save(spec, out)
    st = spec["stats"]
    if st["fallback_categories"]:
        typer.secho(
            f"warning: default-size boxes for {', '.join(st['fallback_categories'])} (not in the catalog)",
            fg="yellow",
            err=True,
        )
    typer.echo(
        f"{out}: blocks {st['blocks']}, {st['sidewalks']} sidewalks, {st['crosswalks']} crosswalks, "
        f"{st['objects']} objects ({st['refused_total']} refused), {len(spec['terrain'])} terrain patches, "
        f"street {st['street_length_m']:.0f} m"
    )


@app.command()
def render(
    scene: Path = typer.Argument(..., exists=True, dir_okay=False, readable=True, help="Scene spec JSON."),
    out: Path = typer.Option(..., "--out", "-o", help="PNG to write."),
    dpi: int = typer.Option(150, min=10, max=1200, help="Resolution (dots per inch)."),
) -> None:
    """Render a scene spec top-down to PNG."""
    from sim.scene import Scene
    from sim.scene.plot import render_scene

    _file_out(out, "scene.png")
    # Scene.load names a file that is not JSON, or the field that is wrong, as a one-line error (exit 2).
    typer.echo(str(render_scene(Scene.load(scene), out, dpi=dpi)))


@app.command()
def dataset(
    out: Path = typer.Option(..., "--out", "-o", help="Output folder (scenes/*.json, index.jsonl, index.parquet)."),
    split: Split = typer.Option(
        "train", help="train | test (templates a-f) | unseen | finetune (template g, held-out categories)."
    ),
    count: int = typer.Option(100, min=1, max=MAX_COUNT, help="Number of scenes."),
    blocks: str = typer.Option(str(DEFAULT_CONFIG["blocks"]), help="Blocks per scene (count 1-64 or codes)."),
    object_density: float = typer.Option(
        DEFAULT_CONFIG["object_density"], "--object-density", help="Object density rho_s, a finite number in [0, 50]."
    ),
    terrain_density: float = _terrain_density_option(),
    catalog: Path | None = typer.Option(None, help=f"Asset catalog (default: {DEFAULT_CATALOG} if present)."),
    workers: int | None = workers_option(
        help="Worker processes (process; default: every core), or scenes at once "
        "on the cluster (ray; default: every cluster CPU)."
    ),
    executor: Executor | None = typer.Option(
        None, help=EXECUTOR_HELP + " Default: process with --workers > 1, else local."
    ),
    address: str | None = address_option(),
    preset: Preset = typer.Option(
        "metaurban12k",
        help="Scene preset: metaurban12k (the paper's density, the "
        "default) or none (the generator's plain defaults, sparser scenes).",
    ),
) -> None:
    """Generate a MetaUrban-12K-style split: one JSON per scene plus an index of per-scene summaries.

    By default the scenes follow the `metaurban12k` preset, whose statistics match the paper's MetaUrban-12K
    (docs/scenes.md); `--preset none` gives the generator's plain defaults.

    Resumable: a rerun into the same folder keeps the complete scene files of the same settings and generates
    only the missing or corrupt ones. Scenes can be generated by a process pool or a Ray cluster (--executor);
    scene k's seed depends on k alone, so every executor writes the same files.
    """
    import time

    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from sim.scene.config import resolve_config
    from sim.scene.dataset import build_dataset, split_config

    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out} is a file; give a folder for the dataset")
    ex = check_executor_args(executor, address) if executor is not None else None
    if ex is None and address is not None:
        raise UsageError(f"--address {address} names a Ray cluster; add --executor ray (or leave out --address)")
    base = {"blocks": _blocks(blocks), "object_density": object_density, "terrain": {"density": terrain_density}}
    if preset.value != "none":
        base["preset"] = preset.value
    resolve_config(split_config(split.value, base)[0])  # bad values fail before the catalog warning and the bar
    cat = _catalog(catalog)
    t0 = time.perf_counter()
    cols = (
        TextColumn(f"[bold]{split.value}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
    )
    nodes: dict[str, int] = {}
    with _catalog_errors(), Progress(*cols) as bar:
        task = bar.add_task(split.value, total=count)
        rows = build_dataset(
            split.value,
            count,
            out,
            base=base,
            catalog=cat,
            workers=workers,
            progress=lambda n: bar.advance(task, n),
            executor=ex,
            address=address,
            nodes=nodes,
        )
    dt = time.perf_counter() - t0
    objs = sum(r["objects"] for r in rows)
    where = f", on {len(nodes)} Ray node(s)" if ex == "ray" else ""
    typer.echo(f"{out}: {len(rows)} scenes, {objs} objects, {dt:.1f} s ({len(rows) / dt:.1f} scenes/s){where}")


@app.command()
def stats(
    directory: Path = typer.Argument(
        ..., exists=True, file_okay=False, help="Dataset folder written by `curbside scenes dataset`."
    ),
    vs_paper: bool = typer.Option(False, "--vs-paper", help="Print each MetaUrban-12K statistic beside ours (+ PNG)."),
    route_preset: RoutePreset = typer.Option(
        "metaurban12k",
        help="Routes and agent density for --vs-paper: short (the "
        "default tasks) or metaurban12k (the paper-scale preset).",
    ),
    seed: int = typer.Option(0, min=0, help="Seed of the route draws (--vs-paper)."),
) -> None:
    """Write a dataset's statistics (objects per scene, object area, street length) as PNG and JSON."""
    from sim.scene.dataset import dataset_stats

    st, png, js = dataset_stats(directory)
    typer.echo(
        f"{st['scenes']} scenes: objects {st['objects']['mean']:.1f}±{st['objects']['std']:.1f}, "
        f"object area {st['object_area_m2']['mean']:.1f} m², street {st['street_length_m']['mean']:.0f} m"
    )
    typer.echo(f"{png}\n{js}")
    if not vs_paper:
        return
    from rich.console import Console
    from rich.progress import track
    from rich.table import Table

    from sim.scene.paper_stats import LABELS, dataset_vs_paper, write_vs_paper

    bar = iter(track(range(st["scenes"]), description="scenes vs paper", transient=True))
    from sim.tasks.pointnav import ROUTE_LENGTHS

    preset_name = route_preset.value
    from sim.tasks.socialnav import PRESETS as SOCIALNAV_PRESETS

    density = SOCIALNAV_PRESETS.get(preset_name, {}).get("agents", {}).get("dynamic_density")
    lo, hi = ROUTE_LENGTHS[preset_name]

    def advance(n: int) -> None:
        next(bar, None)

    result = dataset_vs_paper(
        directory,
        seed=seed,
        route_length=(lo, hi),
        agent_density=density,
        progress=advance,
    )
    table = Table(
        title=f"{result['scenes']} scenes vs MetaUrban-12K (routes drawn in {result['route_length']} m); "
        "meets: within 25 % of the paper's mean, or its bound for >= and >"
    )
    for col in ("statistic", "curbside (min-max)", "paper", "ratio", "meets"):
        table.add_column(col, justify="left" if col == "statistic" else "right")
    for k, row in result["table"].items():
        table.add_row(
            LABELS[k],
            f"{row['ours']:.3g} ({row['min']:.3g}-{row['max']:.3g})",
            row["paper_text"],
            f"{row['ratio']:.2f}",
            "yes" if row["meets"] else "no",
        )
    Console(width=max(Console().width, 110)).print(table)
    js2, png2 = write_vs_paper(result, directory)
    typer.echo(f"{png2}\n{js2}")

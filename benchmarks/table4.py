"""MetaUrban Table 4 on curbside's runways: x-displacement and time until the trial ends (toppled, stuck, much slower,
or the runway's end) for the delivery bot, the wheelchair and the mobility scooter driving straight
ahead on three runways of increasing difficulty (sim.terrain.runway), beside the paper's figures. Every machine holds
the same speed, PAPER_SPEED (5 m/s: the paper's x-displacement over time to fall is 4.9-5.1 m/s for all three
machines), with an ideal traction-limited drive, so the trial compares bodies and wheels on the terrain;
`--speed 0` drives each machine at full throttle with its own engine and top speed instead.

    python benchmarks/table4.py --seeds 10 --out benchmarks/results/terrain

Prints a table (mean over seeds, each seed a different runway), whether each runway ranks the machines as the paper
does, and writes table4.csv, table4.json and table4.png to --out.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.plots import beside_paper, save_panels  # noqa: E402
from sim.terrain.runway import PAPER_SPEED, RUNWAYS, drive_forward  # noqa: E402

MACHINES = ("delivery_bot", "wheelchair", "mobility_scooter")
# MetaUrban (ICLR 2025) Table 4: x-displacement (m) per runway and machine; time to fall (s) on slopes.
PAPER_X = {"slopes": (31.90, 34.58, 38.07), "stairs": (38.55, 38.94, 38.67), "roughs": (28.06, 31.91, 34.17)}
PAPER_TIME = {"slopes": (6.3, 6.9, 7.7)}


def ranking(values: tuple[float, ...]) -> tuple[int, ...]:
    """The machines' order from shortest to longest distance (indices into MACHINES)."""
    return tuple(int(i) for i in np.argsort(values, kind="stable"))


def main(seeds: int = 10, out: Path | None = None, model: str = "force", speed: float | None = PAPER_SPEED) -> dict:
    """Run every machine on every runway for `seeds` runways each (at `speed`, or full throttle when None); print
    and write the table."""
    from rich.progress import track

    rows = []
    jobs = [(r, m, s) for r in RUNWAYS for m in MACHINES for s in range(seeds)]
    for runway, machine, seed in track(jobs, description="table 4 trials"):
        rows.append(drive_forward(machine, runway, seed, model=model, speed=speed))
    table: dict = {}
    print(f"{'runway':8} {'machine':18} {'x (m)':>14} {'paper x':>8} {'time (s)':>14} {'paper t':>8}  ends")
    for runway in RUNWAYS:
        means = []
        for k, machine in enumerate(MACHINES):
            rs = [r for r in rows if r["runway"] == runway and r["machine"] == machine]
            x = np.array([r["x_displacement"] for r in rs])
            t = np.array([r["time"] for r in rs])
            ends = {reason: sum(r["reason"] == reason for r in rs) for reason in sorted({r["reason"] for r in rs})}
            means.append(float(x.mean()))
            table[f"{runway}/{machine}"] = {
                "x_mean": float(x.mean()),
                "x_std": float(x.std()),
                "time_mean": float(t.mean()),
                "time_std": float(t.std()),
                "ends": ends,
                "paper_x": PAPER_X[runway][k],
                "paper_time": PAPER_TIME.get(runway, (None,) * 3)[k],
            }
            pt = PAPER_TIME.get(runway, (None,) * 3)[k]
            print(
                f"{runway:8} {machine:18} {x.mean():7.2f} ±{x.std():5.2f} {PAPER_X[runway][k]:8.2f} "
                f"{t.mean():7.2f} ±{t.std():5.2f} {'' if pt is None else f'{pt:8.1f}':>8}  {ends}"
            )
        same = ranking(tuple(means)) == ranking(PAPER_X[runway])
        table[f"{runway}/same_order_as_paper"] = same
        print(
            f"{runway:8} order {' < '.join(MACHINES[i] for i in ranking(tuple(means)))}; paper "
            f"{' < '.join(MACHINES[i] for i in ranking(PAPER_X[runway]))}: {'same' if same else 'different'}"
        )
    matched = sum(table[f"{r}/same_order_as_paper"] for r in RUNWAYS)
    print(f"runways ranked as in the paper: {matched} of {len(RUNWAYS)}")
    table["runways_ranked_as_paper"] = matched
    if out is not None:
        _write(Path(out), rows, table)
    return table


def _write(out: Path, rows: list[dict], table: dict) -> None:
    """table4.csv (every trial), table4.json (the summary) and table4.png (bars beside the paper's)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    with open(out / "table4.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    (out / "table4.json").write_text(json.dumps(table, indent=2, sort_keys=True))
    fig, axes = plt.subplots(1, len(RUNWAYS), figsize=(4 * len(RUNWAYS), 3.6), sharey=True)
    for ax, runway in zip(axes, RUNWAYS):
        ours = [table[f"{runway}/{m}"]["x_mean"] for m in MACHINES]
        err = [table[f"{runway}/{m}"]["x_std"] for m in MACHINES]
        same = "same" if table[f"{runway}/same_order_as_paper"] else "different"
        beside_paper(
            ax,
            ["bot", "wheelchair", "scooter"],
            ours,
            PAPER_X[runway],
            ours_label="curbside",
            paper_label="MetaUrban Table 4",
            title=f"{runway} ({same} order)",
            err=err,
        )
    save_panels(fig, axes, "x-displacement (m)", out / "table4.png")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=10, help="runways per runway kind (each seed a different terrain)")
    ap.add_argument("--out", type=Path, default=None, help="folder for table4.csv, .json and .png")
    ap.add_argument(
        "--model",
        choices=("force", "wheels"),
        default="force",
        help="machine model: the envs' force model, or driven wheel links (sim.terrain.wheels, experimental)",
    )
    ap.add_argument(
        "--speed",
        type=float,
        default=PAPER_SPEED,
        help=f"one speed (m/s) every machine holds (default {PAPER_SPEED}, the paper's); 0: full throttle",
    )
    a = ap.parse_args()
    if not 0.0 <= a.speed < 100.0:  # NaN fails too
        ap.error(f"--speed must be 0 (full throttle) or a speed in m/s below 100, got {a.speed}")
    main(a.seeds, a.out, a.model, a.speed or None)

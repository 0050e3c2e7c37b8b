"""The paper's numbers in curbside/train/paper.py equal those of docs/paper_numbers.md, transcribed separately from
the paper: all 84 cells of Table 1, Table 2, Table 5 and the seed robustness."""

from __future__ import annotations

import re
from pathlib import Path

from curbside.train.paper import (
    METHOD_NAMES,
    PAPER_SEED_ROBUSTNESS,
    PAPER_TABLE1,
    PAPER_TABLE2,
    PAPER_TABLE5_HORIZON,
    PAPER_TABLE5_PEDESTRIANS,
)

DOC = (Path(__file__).resolve().parents[2] / "docs" / "paper_numbers.md").read_text()
MACHINE_ROWS = {
    "COCO base": "delivery_bot",
    "COCO mod-1": "delivery_bot_mod1",
    "COCO mod-2": "delivery_bot_mod2",
    "wheelchair": "wheelchair",
    "mobility scooter": "mobility_scooter",
}


def _rows(section: str) -> list[list[str]]:
    text = DOC.split(f"## {section}")[1].split("\n## ")[0]
    return [
        [c.strip() for c in line.strip().strip("|").split("|")]
        for line in text.splitlines()
        if line.startswith("|")
        and not line.startswith("|---")
        and not line.startswith("| method")
        and not line.startswith("| machine")
    ]


def _cell(text: str) -> tuple[float, ...]:
    return tuple(
        float(v) / 100 if "%" in part else float(v) for part in text.split("/") for v in re.findall(r"[\d.]+", part)
    )


def test_all_84_table1_cells_equal_the_papers() -> None:
    names = {v: k for k, v in METHOD_NAMES.items()}
    columns = (("PointNav", "test"), ("PointNav", "unseen"), ("SocialNav", "test"), ("SocialNav", "unseen"))
    seen = 0
    for row in _rows("Table 1"):
        method = names[row[0]]
        for (task, split), text in zip(columns, row[1:]):
            sr, second, cost = _cell(text)
            ours = PAPER_TABLE1[(task, split, method)]
            assert ours == {"sr": sr, "spl" if task == "PointNav" else "sns": second, "cost": cost}, (
                task,
                split,
                method,
            )
            seen += 3
    assert seen == 84 and len(PAPER_TABLE1) == 28
    robust = re.search(r"SR ([\d.]+) \+/- ([\d.]+) on test, ([\d.]+) \+/- ([\d.]+)", DOC.replace("\n", " ")).groups()
    assert (
        PAPER_SEED_ROBUSTNESS["test"]["sr"],
        PAPER_SEED_ROBUSTNESS["test"]["sr_std"],
        PAPER_SEED_ROBUSTNESS["unseen"]["sr"],
        PAPER_SEED_ROBUSTNESS["unseen"]["sr_std"],
    ) == tuple(map(float, robust))


def test_table2_and_table5_equal_the_papers() -> None:
    for row in _rows("Table 2"):
        machine = MACHINE_ROWS[row[0]]
        sr, spl, cost = (_cell(c) for c in row[4:7])
        for k, block in enumerate("SX"):
            assert PAPER_TABLE2[machine][block] == {"sr": sr[k], "spl": spl[k], "cost": cost[k]}, (machine, block)
    assert len(PAPER_TABLE2) == 5
    text = DOC.split("## Table 5")[1].replace("\n", " ")
    horizon = re.search(r"SR (\d+) % vs (\d+) %; SPL ([\d.]+) vs (\d+\.\d+)", text).groups()
    assert (PAPER_TABLE5_HORIZON["10 m"]["sr"], PAPER_TABLE5_HORIZON["410 m"]["sr"]) == (
        float(horizon[0]) / 100,
        float(horizon[1]) / 100,
    )
    assert (PAPER_TABLE5_HORIZON["10 m"]["spl"], PAPER_TABLE5_HORIZON["410 m"]["spl"]) == (
        float(horizon[2]),
        float(horizon[3]),
    )
    srs = [float(v) / 100 for v in re.search(r"SR (\d+) % / (\d+) % / (\d+) % / (\d+) %", text).groups()]
    costs = [float(v) for v in re.search(r"Cost (\d+\.\d+) / (\d+\.\d+) / (\d+\.\d+) / (\d+\.\d+)", text).groups()]
    assert [PAPER_TABLE5_PEDESTRIANS[s]["sr"] for s in "1234"] == srs
    assert [PAPER_TABLE5_PEDESTRIANS[s]["cost"] for s in "1234"] == costs

"""The ranking campaign: its statistics on records with a known answer (per-rank counts, the calibration bins and
the Brier score, the rank-1-vs-rank-k test), and a small real run that validates every rank and writes its files."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from softsig_service.experiments.ranking import run_ranking, summarize


def _record(hand: str, rank: int, quality: float, success: bool, model: str = "capture") -> dict[str, object]:
    return {"hand": hand, "rank": rank, "quality": quality, "quality_model": model, "geometric_quality": 1.0 - quality,
            "success": success}  # fmt: skip


def test_the_statistics_of_known_records() -> None:
    records = [_record("a", 1, 0.9, True) for _ in range(9)] + [_record("a", 1, 0.9, False)]
    records += [_record("a", 2, 0.1, False) for _ in range(9)] + [_record("a", 2, 0.1, True)]
    s = summarize(records, 2)
    assert [(r["successes"], r["trials"]) for r in s["per_rank"]] == [(9, 10), (1, 10)]
    assert s["rank1_vs_rankk"]["rank_k"] == 2 and s["rank1_vs_rankk"]["rank1_greater"] < 0.01
    capture = s["calibration"]["capture"]
    assert capture["brier"] == pytest.approx(0.01 * 18 / 20 + 0.81 * 2 / 20)
    assert [(b["n"], b["predicted"], b["observed"]) for b in capture["bins"]] == [
        (10, pytest.approx(0.1), 0.1),
        (10, pytest.approx(0.9), 0.9),
    ]
    geometric = s["calibration"]["geometric"]  # 1 - quality: exactly wrong
    assert geometric["brier"] == pytest.approx(0.81 * 18 / 20 + 0.01 * 2 / 20)


def test_a_small_run_validates_every_rank_and_writes_its_files(tmp_path: Path) -> None:
    s = run_ranking(tmp_path, hands=("parallel_gripper",), k=2, trials=1, condition=1)
    assert [r["trials"] for r in s["per_rank"]] == [6, 6]  # 3 objects x 2 strategies, one trial per grasp
    data = json.loads((tmp_path / "ranking.json").read_text())
    assert len(data["records"]) == 12 and {r["rank"] for r in data["records"]} == {1, 2}
    assert (tmp_path / "ranking.png").read_bytes()[:4] == b"\x89PNG" and "rank 1" in (
        tmp_path / "ranking.md"
    ).read_text()

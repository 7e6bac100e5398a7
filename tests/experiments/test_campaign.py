"""Campaigns: seeds, a tiny grid in worker processes, resuming, statistics, the report, Ray, the CLI."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path
from typing import Any

import pytest
import typer
from typer.testing import CliRunner

from softsig_service.cli.experiments import experiment_app
from softsig_service.errors import Conflict, InvalidInput
from softsig_service.experiments.campaign import read_records, run_campaign
from softsig_service.experiments.campaign_spec import PAPER_TABLE1, TABLE1_CONDITIONS, CampaignSpec, trial_seed
from softsig_service.experiments.report import report_markdown, write_report
from softsig_service.experiments.statistics import fisher_p, summarize, wilson_interval
from softsig_service.experiments.trial import run_trial
from softsig_service.objects import builtin_object

TINY = CampaignSpec(hand="pisa_iit_softhand", conditions=((0.1, 0.01),), trials=1, seed=3)
"""One condition, three objects, two strategies, one trial per cell: 6 trials."""
OUTCOME_KEYS = ("key", "seed", "success", "reason", "lift_height", "max_lift", "perturbation")


FLOAT_TOLERANCE = 1e-3
"""[m] a worker process may differ from this one in the last bits; contact dynamics amplify them, most in the
transient peak ``max_lift`` of a dropped object (seen: 1e-4 m). Successes and reasons compare exactly."""


def _approx(value: Any) -> Any:
    if isinstance(value, float):
        return pytest.approx(value, abs=FLOAT_TOLERANCE)
    if isinstance(value, dict):
        return {k: _approx(v) for k, v in value.items()}
    return value


def _outcomes(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The outcome fields; floats compare to within :data:`FLOAT_TOLERANCE` (use as the expected side)."""
    return [{k: _approx(r[k]) for k in OUTCOME_KEYS} for r in records]


def _raw(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{k: r[k] for k in OUTCOME_KEYS} for r in records]


def _lines(path: Path) -> list[str]:
    return [ln for ln in path.read_text(encoding="utf-8").splitlines() if ln.strip()]


# -- seeds and the grid ----------------------------------------------------------------------------------------


def test_trial_seeds_are_deterministic_and_distinct() -> None:
    specs = CampaignSpec(trials=20, seed=0).trial_specs()
    assert len(specs) == 3 * 3 * 2 * 20
    assert len({t.key for t in specs}) == len(specs)
    assert len({t.seed for t in specs}) == len(specs)
    assert [t.seed for t in specs] == [t.seed for t in CampaignSpec(trials=20, seed=0).trial_specs()]
    assert specs[0].seed != CampaignSpec(trials=20, seed=1).trial_specs()[0].seed
    assert trial_seed(0, (1, 2, 1), 5) == next(
        t.seed for t in specs if (t.condition, t.object, t.strategy, t.trial) == (1, "cylinder", "C", 5)
    )
    # more trials per cell keep the seeds of the first ones
    assert [t.seed for t in CampaignSpec(trials=5).trial_specs() if t.trial < 5][:5] == [s.seed for s in specs[:5]]


def test_bad_specs_are_refused(tmp_path: Path) -> None:
    with pytest.raises(InvalidInput):
        CampaignSpec(trials=0)
    with pytest.raises(InvalidInput):
        CampaignSpec(objects=("teapot",))
    with pytest.raises(InvalidInput):
        CampaignSpec(conditions=((-0.1, 0.0),))
    with pytest.raises(InvalidInput):
        run_campaign(TINY, tmp_path, backend="dask")  # type: ignore[arg-type]
    with pytest.raises(InvalidInput):
        run_campaign(TINY, tmp_path, workers=0)


# -- running ---------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def tiny_local(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Any]:
    out = tmp_path_factory.mktemp("tiny")
    return out, run_campaign(TINY, out, workers=2)


def test_tiny_grid_runs_in_worker_processes(tiny_local: tuple[Path, Any]) -> None:
    out, result = tiny_local
    assert result.complete and result.ran == 6 and result.skipped == 0
    assert len(result.records) == 6
    assert [r["index"] for r in result.records] == list(range(6))
    assert {r["object"] for r in result.records} == {"box", "apple", "cylinder"}
    for name in ("campaign.json", "trials.jsonl", "results.json", "results.csv", "report.md", "table1.png"):
        assert (out / name).is_file(), name
    assert (out / "table1.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = list(csv.DictReader((out / "results.csv").read_text(encoding="utf-8").splitlines()))
    assert len(rows) == 6 and rows[0]["key"] == "c0/box/S/0" and rows[0]["seed"] == str(result.records[0]["seed"])
    saved = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert saved["campaign"] == TINY.to_json_dict() and len(saved["records"]) == 6
    counts = {(c["object"], s): c[s]["successes"] for c in saved["summary"]["cells"] for s in ("S", "C")}
    for r in result.records:
        assert counts[(r["object"], r["strategy"])] == int(r["success"])
    report = (out / "report.md").read_text(encoding="utf-8")
    assert "| object | σr=0.1 rad, σt=0.01 m |" in report
    assert "Fisher" in report and "Wilson" in report


def test_workers_give_the_same_outcomes_as_this_process(tiny_local: tuple[Path, Any]) -> None:
    _, result = tiny_local
    for r in result.records:
        again = run_trial(
            r["hand"], builtin_object(r["object"]), r["strategy"], seed=r["seed"], sigma_r=0.1, sigma_t=0.01
        ).to_json_dict()
        again["key"] = r["key"]
        assert _raw([again]) == _outcomes([r])


def test_resume_after_an_interruption_redoes_nothing(tmp_path: Path) -> None:
    spec = CampaignSpec(conditions=((0.2, 0.02),), objects=("box", "apple"), trials=2, seed=11)  # 8 trials
    done_at_interrupt: list[int] = []

    def interrupt_after_three(done: int, total: int) -> None:
        if done == 3:
            done_at_interrupt.append(done)
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_campaign(spec, tmp_path, workers=2, progress=interrupt_after_three)
    assert done_at_interrupt == [3]
    first = _lines(tmp_path / "trials.jsonl")
    assert len(first) == 3
    with (tmp_path / "trials.jsonl").open("a", encoding="utf-8") as f:
        f.write('{"key": "c0/apple/C/1", "seed": 1, "succ')  # a torn last line of a killed run

    partial = run_campaign(spec, tmp_path, workers=1, max_trials=2)
    assert partial.ran == 2 and partial.skipped == 3 and not partial.complete and not partial.files
    final = run_campaign(spec, tmp_path, workers=1)
    assert final.ran == 3 and final.skipped == 5 and final.complete
    lines = _lines(tmp_path / "trials.jsonl")
    assert lines[:3] == first  # the first records are untouched
    keys = [r["key"] for r in read_records(tmp_path / "trials.jsonl")]
    assert len(keys) == 8 and len(set(keys)) == 8  # every trial exactly once, the torn line ignored
    assert run_campaign(spec, tmp_path, workers=1).ran == 0

    fresh = run_campaign(spec, tmp_path / "fresh", workers=1)
    assert _raw(fresh.records) == _outcomes(final.records)  # resuming changed no outcome


def test_identical_trials_are_simulated_once_and_recorded_for_each(tmp_path: Path) -> None:
    """A nominal cell draws the zero perturbation for every seed: one simulation, its record replicated under each
    trial's labels, the same outcomes as simulating all of them; a resumed campaign replicates a recorded one."""
    spec = CampaignSpec(conditions=((0.0, 0.0), (0.1, 0.01)), objects=("box",), strategies=("C",), trials=3, seed=5)
    simulated: list[str] = []
    reused = run_campaign(spec, tmp_path / "reused", workers=1)
    every = run_campaign(spec, tmp_path / "every", workers=1, reuse_identical=False)
    assert _raw(reused.records) == _outcomes(every.records)
    by_key = {r["key"]: r for r in reused.records}
    nominal = [by_key[f"c0/box/C/{k}"] for k in range(3)]
    assert "same_as" not in nominal[0] and nominal[0]["wall_time"] > 0.0
    for k, r in enumerate(nominal[1:], start=1):
        assert r["same_as"] == "c0/box/C/0" and r["wall_time"] == 0.0 and r["trial"] == k
        assert r["seed"] == trial_seed(5, (0, 0, 0), k) != nominal[0]["seed"]
        assert {key: r[key] for key in ("success", "reason", "lift_height", "diagnosis")} == {
            key: nominal[0][key] for key in ("success", "reason", "lift_height", "diagnosis")
        }
    assert all("same_as" not in by_key[f"c1/box/C/{k}"] for k in range(3))  # distinct perturbations
    assert not any("same_as" in r for r in every.records)

    resumed_dir = tmp_path / "resumed"
    first = run_campaign(spec, resumed_dir, workers=1, max_trials=1)
    assert first.ran == 1 and [r["key"] for r in first.records] == ["c0/box/C/0"]
    rest = run_campaign(spec, resumed_dir, workers=1, progress=lambda done, total: simulated.append(f"{done}/{total}"))
    assert rest.ran == 5 and rest.skipped == 1 and rest.complete
    assert simulated[:2] == ["2/6", "3/6"]  # the two replicas come first, before any simulation
    assert _raw(rest.records) == _outcomes(reused.records)


def test_another_campaign_in_the_same_folder_is_refused(tmp_path: Path) -> None:
    spec = CampaignSpec(conditions=((0.0, 0.0),), objects=("apple",), strategies=("S",), trials=1)
    run_campaign(spec, tmp_path, workers=1)
    with pytest.raises(Conflict):
        run_campaign(CampaignSpec(conditions=((0.0, 0.0),), objects=("apple",), strategies=("S",), trials=1,
                                  seed=1), tmp_path, workers=1)  # fmt: skip


def test_ray_backend_without_ray_says_how_to_install(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)
    with pytest.raises(InvalidInput, match="pip install"):
        run_campaign(TINY, tmp_path, backend="ray", workers=2)


@pytest.mark.slow
def test_ray_backend_on_a_local_cluster(tmp_path: Path, tiny_local: tuple[Path, Any]) -> None:
    pytest.importorskip("ray")
    result = run_campaign(TINY, tmp_path, backend="ray", workers=2)
    assert result.complete and result.ran == 6
    assert _raw(result.records) == _outcomes(tiny_local[1].records)


# -- statistics and the report ---------------------------------------------------------------------------------


def test_wilson_and_fisher_values() -> None:
    lo, hi = wilson_interval(17, 20)
    assert (lo, hi) == pytest.approx((0.6396, 0.9476), abs=1e-4)
    assert wilson_interval(0, 20)[0] == 0.0 and wilson_interval(20, 20)[1] == pytest.approx(1.0)
    p = fisher_p(3, 20, 11, 20)  # the paper's box at the largest uncertainty
    assert p["two_sided"] == pytest.approx(0.0187, abs=1e-3)
    assert p["c_greater"] == pytest.approx(0.00935, abs=1e-4)
    assert fisher_p(10, 20, 10, 20)["two_sided"] == pytest.approx(1.0)


def _synthetic_table1(spec: CampaignSpec) -> list[dict[str, Any]]:
    """Records that reproduce the paper's counts exactly (S and C per cell)."""
    recs: list[dict[str, Any]] = []
    for t in spec.trial_specs():
        s, c = PAPER_TABLE1[t.object][t.condition]
        k = s if t.strategy == "S" else c
        ok = t.trial < k
        recs.append({"key": t.key, "index": t.index, "condition": t.condition, "object": t.object,
                     "strategy": t.strategy, "trial": t.trial, "seed": t.seed, "success": ok,
                     "reason": None if ok else "dropped", "lift_height": 0.15 if ok else 0.0,
                     "perturbation": {"d_yaw": 0.0, "dx": 0.0, "dy": 0.0}})  # fmt: skip
    return recs


def test_report_has_the_table1_layout_and_the_papers_numbers(tmp_path: Path) -> None:
    spec = CampaignSpec(trials=20)
    recs = _synthetic_table1(spec)
    summary = summarize(spec, recs)
    report = report_markdown(spec, summary)
    assert "| object | σr=0 rad, σt=0 m | σr=0.1 rad, σt=0.01 m | σr=0.2 rad, σt=0.02 m |" in report
    assert "| box | 17 / 20 (N=20) | 15 / 16 (N=20) | 3 / 11 (N=20) |" in report  # ours (= the paper's here)
    assert "| box | 17 / 20 | 15 / 16 | 3 / 11 |" in report  # the paper's
    assert "| cylinder | 18 / 19 | 10 / 16 | 8 / 11 |" in report
    cell = next(c for c in summary["cells"] if c["object"] == "box" and c["condition"] == 2)
    assert cell["fisher"] == cell["paper"]["fisher"]
    pooled = summary["pooled_per_condition"][2]
    assert (pooled["S"]["successes"], pooled["C"]["successes"]) == (3 + 17 + 8, 11 + 15 + 11)
    assert summary["pooled"]["S"]["trials"] == 180
    assert summary["pooled"]["S"]["successes"] == sum(s for row in PAPER_TABLE1.values() for s, _ in row)
    assert cell["reasons"]["S"] == {"dropped": 17}
    files = write_report(spec, recs, tmp_path)
    assert Path(files["chart"]).stat().st_size > 10_000
    assert len(Path(files["csv"]).read_text(encoding="utf-8").splitlines()) == 361
    assert spec.conditions == TABLE1_CONDITIONS


def test_report_without_the_papers_grid_has_no_paper_columns() -> None:
    spec = CampaignSpec(conditions=((0.3, 0.03),), objects=("box",), trials=2)
    recs = [{"key": t.key, "index": t.index, "condition": 0, "object": "box", "strategy": t.strategy,
             "success": t.strategy == "C", "reason": None if t.strategy == "C" else "no_contact"}
            for t in spec.trial_specs()]  # fmt: skip
    summary = summarize(spec, recs)
    assert not summary["paper_available"] and "paper" not in summary["cells"][0]
    report = report_markdown(spec, summary)
    assert "real-robot" not in report and "| box | 0 / 2 (N=2) |" in report


# -- the CLI ---------------------------------------------------------------------------------------------------


def test_experiment_table1_command(tmp_path: Path) -> None:
    app = typer.Typer(pretty_exceptions_enable=False)
    app.add_typer(experiment_app, name="experiment")
    args = ["experiment", "table1", "--trials", "1", "--seed", "2", "--out", str(tmp_path), "--workers", "2",
            "--no-progress"]  # fmt: skip
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    assert "| box |" in res.stdout and "The paper's real-robot counts" in res.stdout
    assert "ran 18 trials" in res.stdout
    assert len(_lines(tmp_path / "trials.jsonl")) == 18
    again = CliRunner().invoke(app, args)
    assert again.exit_code == 0 and "ran 0 trials, skipped 18" in again.stdout
    bad = CliRunner().invoke(app, [*args[:-1], "--backend", "mpi"])
    assert bad.exit_code == 2 and "unknown backend" in bad.output
    other = CliRunner().invoke(app, ["experiment", "table1", "--trials", "2", "--out", str(tmp_path)])
    assert other.exit_code == 2 and "different campaign" in other.output


def test_experiment_options_are_recorded_and_passed_to_every_plan(tmp_path: Path) -> None:
    app = typer.Typer(pretty_exceptions_enable=False)
    app.add_typer(experiment_app, name="experiment")
    args = ["experiment", "table1", "--trials", "1", "--seed", "5", "--out", str(tmp_path), "--workers", "1",
            "--no-progress", "--conditions", "2", "--strategies", "C", "--cs-method", "ellipsoid",
            "--criterion", "relative", "--placement", "previous"]  # fmt: skip
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    spec = json.loads((tmp_path / "campaign.json").read_text(encoding="utf-8"))
    assert spec["conditions"] == [[0.2, 0.02]] and spec["strategies"] == ["C"]
    assert (spec["cs_method"], spec["criterion"], spec["placement"]) == ("ellipsoid", "relative", "previous")
    assert "relative criterion; placement: previous" in res.stdout
    records = [json.loads(ln) for ln in _lines(tmp_path / "trials.jsonl")]
    assert len(records) == 3
    # the relative criterion elects the SoftHand's palm normal, which a top grasp cannot align: every C plan fails
    assert all(r["reason"] == "alignment_impossible" for r in records)
    for bad_args, message in ((["--conditions", "5"], "unknown condition index"),
                              (["--placement", "middle"], "unknown placement"),
                              (["--criterion", "largest"], "unknown criterion")):  # fmt: skip
        bad = CliRunner().invoke(app, ["experiment", "table1", "--out", str(tmp_path / "x"), *bad_args])
        assert bad.exit_code == 2 and message in bad.output, bad.output

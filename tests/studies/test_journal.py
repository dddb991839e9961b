"""The resume journal: round trips, damaged and edited rows, older folders migrated,
definitions, fresh starts."""

from __future__ import annotations

import json
import logging
import math
import os
from pathlib import Path

import pytest

from pnp_twin.studies.journal import REPLACED, Journal, changed_text, differences, journaled
from pnp_twin.studies.lock import FolderBusy
from pnp_twin.studies.plan import StudyError, build_plan
from pnp_twin.twin import load_scenario, with_overrides


@pytest.fixture(scope="module")
def plan():
    line = with_overrides(load_scenario("paper_baseline"), {"duration": 20, "warmup": 2})
    return build_plan(line, grid={"feeder.rate": [8.0, 12.0]}, policies=["SD"], replications=2)


def definition(plan, **change):
    return {"kind": "sweep", **plan.definition(), **change}


def fake_row(spec, **change):
    row = {
        "run_id": spec.run_id,
        "point": spec.point,
        "feeder.rate": spec.values["feeder.rate"],
        "policy": spec.policy,
        "replication": spec.replication,
        "seed": spec.seed,
        "scenario": "paper_baseline",
        "gripping_rate": 91.25,
        "parts_presented": 80,
        "parts_picked": 73,
        "cycle_time_mean": math.nan,
        "r1_picks": 20,
        "rule_SD": 73,
        "wall_time": 0.01,
    }
    return {**row, **change}


def opened(folder: Path, plan, **kw) -> Journal:
    return Journal(folder, definition(plan), **kw)


def test_a_row_reads_back_exactly_nan_included(plan, tmp_path):
    j = opened(tmp_path, plan)
    spec = plan.specs()[0]
    j.record(fake_row(spec))
    back = j.load(spec)
    assert back is not None and math.isnan(back.pop("cycle_time_mean"))
    want = fake_row(spec)
    want.pop("cycle_time_mean")
    assert back == want
    assert j.load(plan.specs()[1]) is None  # not run yet
    j.close()


def legacy_line(row: dict) -> bytes:
    """A row as an earlier version wrote it into a segment (NaN as ``NaN``)."""
    return (json.dumps(row, allow_nan=True, separators=(",", ":")) + "\n").encode()


def test_each_row_is_committed_when_it_is_recorded(plan, tmp_path):
    """No batch, no timer: another process (a watcher, the next session after a kill) sees
    every recorded run at once, and a run recorded again keeps its later row."""
    j = opened(tmp_path, plan)
    specs = plan.specs()
    for n, spec in enumerate(specs[:3], start=1):
        j.record(fake_row(spec))  # in quick succession
        assert journaled(tmp_path / "runs") == {s.run_id for s in specs[:n]}
    assert [p.name for p in (tmp_path / "runs").glob("runs.sqlite")] == ["runs.sqlite"]
    j.record(fake_row(specs[3]))
    j.close()
    j = opened(tmp_path, plan)
    assert all(j.load(s) is not None for s in specs)
    j.record(fake_row(specs[0], wall_time=0.5))
    j.close()
    j = opened(tmp_path, plan)
    assert j.load(specs[0])["wall_time"] == 0.5  # the later row wins
    j.close()


def test_an_older_segment_is_migrated_and_its_damaged_lines_run_again(plan, tmp_path, caplog):
    """An earlier version's segment: a line that is not JSON and a last line cut short by a
    kill are left out (their runs done again), the rest imported once; the file is renamed."""
    specs = plan.specs()
    lines = [legacy_line(fake_row(s)) for s in specs[:3]]
    opened(tmp_path, plan).close()  # the folder's study.json
    segment = tmp_path / "runs" / "000001.jsonl"
    segment.write_bytes(lines[0] + b"{garbage\n" + lines[1] + lines[2][:40])  # killed mid-write
    with caplog.at_level(logging.WARNING):
        j = opened(tmp_path, plan)
        found = j.rows(specs)
    assert [r is not None for r in found] == [True, True, False, False]
    assert (
        "line 4" in caplog.text and "cut short" in caplog.text and "running it again" in caplog.text
    )
    assert "line 2" in caplog.text  # the garbage line, dropped too
    assert not segment.exists() and segment.with_name("000001.jsonl.migrated").is_file()
    back = found[0]
    assert back is not None and math.isnan(back.pop("cycle_time_mean"))  # NaN read back
    j.record(fake_row(specs[2]))
    j.close()
    j = opened(tmp_path, plan)
    assert [r is not None for r in j.rows(specs)] == [True, True, True, False]
    assert journaled(tmp_path / "runs") == {s.run_id for s in specs[:3]}
    j.close()


@pytest.mark.parametrize("text", ["", '{"run_id": "p000-SD-r00", "point": 0, "gri', "\xff\xfe"])
def test_a_truncated_or_empty_run_is_run_again(plan, tmp_path, caplog, text):
    """A run file of a folder journaled before segments (one JSON file per run)."""
    j = opened(tmp_path, plan)
    spec = plan.specs()[0]
    path = tmp_path / "runs" / f"{spec.run_id}.json"
    path.write_bytes(text.encode("latin-1"))
    with caplog.at_level(logging.WARNING):
        assert j.load(spec) is None  # migrated on first read: the damaged file left out
    assert not path.exists()
    assert "is damaged" in caplog.text and "running it again" in caplog.text
    j.close()


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        ({"gripping_rate": 1234.5}, "gripping_rate = 1234.5 is not allowed; a percentage"),
        ({"gripping_rate": "91"}, 'gripping_rate = "91" is not allowed; a number'),
        ({"parts_picked": -3}, "parts_picked = -3 is not allowed; a whole number >= 0"),
        ({"r1_picks": 2.5}, "r1_picks = 2.5 is not allowed"),
        ({"rule_SD": True}, "rule_SD = true is not allowed"),
        ({"wall_time": -1.0}, "wall_time = -1.0 is not allowed; a number >= 0"),
        ({"seed": 7}, "seed = 7 is not this run's"),
        ({"feeder.rate": 9.0}, "feeder.rate = 9.0 is not this run's; expected 8.0"),
        ({"parts_picked": 81}, "parts_picked = 81 is more than parts_presented = 80"),
    ],
)
def test_an_edited_run_is_refused_naming_file_and_field(plan, tmp_path, change, needle):
    j = opened(tmp_path, plan)
    spec = plan.specs()[0]
    j.record(fake_row(spec, **change))
    with pytest.raises(StudyError) as e:
        j.load(spec)
    message = str(e.value)
    assert f"runs.sqlite (run {spec.run_id})" in message and needle in message
    assert "delete that run to run it again" in message and "\n" not in message
    assert f"DELETE FROM runs WHERE key = '{spec.run_id}'" in message
    j.close()
    j = opened(tmp_path, plan)  # from disk, in a later session, alike
    with pytest.raises(StudyError, match=r"runs.sqlite \(run .*delete that run"):
        j.load(spec)
    j.close()


def test_an_edited_row_of_an_older_folder_is_refused_after_migration(plan, tmp_path):
    spec = plan.specs()[0]
    opened(tmp_path, plan).close()  # the folder's study.json
    (tmp_path / "runs" / "000001.jsonl").write_bytes(legacy_line(fake_row(spec, seed=7)))
    j = opened(tmp_path, plan)
    with pytest.raises(StudyError, match=r"runs.sqlite \(run p000-SD-r00\): seed = 7 is not"):
        j.load(spec)
    j.close()


def test_a_row_that_is_not_an_object_is_refused(plan, tmp_path):
    j = opened(tmp_path, plan)
    spec = plan.specs()[0]
    (tmp_path / "runs" / f"{spec.run_id}.json").write_text("[1, 2]")
    with pytest.raises(StudyError, match="holds list, not a run's row; delete the file"):
        j.load(spec)
    j.close()
    (tmp_path / "runs" / f"{spec.run_id}.json").unlink()
    (tmp_path / "runs" / "000001.jsonl").write_text('{"run_id": "p000-SD-r00"}\n[1, 2]\n')
    j = opened(tmp_path, plan)
    with pytest.raises(StudyError, match=r"000001.jsonl line 2: holds list, not a run's row"):
        j.load(spec)
    j.close()


@pytest.mark.parametrize("text", ["", "{", "[]", "\xff"])
def test_a_damaged_study_json_is_one_line(plan, tmp_path, text):
    opened(tmp_path, plan).close()
    (tmp_path / "study.json").write_bytes(text.encode("latin-1"))
    with pytest.raises(StudyError, match=r"study.json: is damaged .*--fresh") as e:
        opened(tmp_path, plan)
    assert "\n" not in str(e.value)
    opened(tmp_path, plan, fresh=True).close()  # --fresh gets past it


def test_a_changed_field_is_named_with_both_values(plan, tmp_path):
    opened(tmp_path, plan).close()
    other = with_overrides(plan.scenario, {"robots.arm_speed": 4.0})
    changed = build_plan(other, grid={"feeder.rate": [8.0, 12.0]}, policies=["SD"])
    with pytest.raises(StudyError) as e:
        Journal(tmp_path, definition(changed))
    assert "scenario.robots.arm_speed was 3.0, now 4.0" in str(e.value)
    assert "--fresh" in str(e.value)


def test_differences_walk_nested_mappings():
    old = {"a": {"b": 1, "c": [1, 2]}, "d": "x"}
    new = {"a": {"b": 2, "c": [1, 2]}, "e": 1}
    assert differences(old, new) == [("a.b", 1, 2), ("d", "x", None), ("e", None, 1)]
    text = changed_text([(f"k{i}", i, i + 1) for i in range(5)])
    assert text.startswith("k0 was 0, now 1; k1 was 1, now 2") and text.endswith("and 2 more")


def test_changing_only_the_replications_keeps_the_runs(plan, tmp_path):
    j = opened(tmp_path, plan)
    for spec in plan.specs():
        j.record(fake_row(spec))
    j.close()
    more = plan.with_replications(4)
    j = Journal(tmp_path, definition(more))
    assert json.loads((tmp_path / "study.json").read_text())["replications"] == 4
    found = j.rows(more.specs())
    assert sum(r is not None for r in found) == 4  # replications 0 and 1 of both points
    assert [s.seed for s in more.specs() if s.replication < 2] == [
        s.seed for s in plan.specs()
    ]  # common random numbers: replication k's seed does not depend on the count
    j.close()


def test_opening_removes_the_temporary_files_of_killed_writes(plan, tmp_path):
    (tmp_path / "runs").mkdir(parents=True)
    (tmp_path / "records").mkdir()
    left = [
        tmp_path / ".results.parquet.0123456789ab.tmp",
        tmp_path / "runs" / ".p000-SD-r00.json.a1b2c3d4e5f6.tmp",
        tmp_path / "records" / ".parts.parquet.ffffffffffff.tmp",
    ]
    for p in left:
        p.write_text("half")
    mine = tmp_path / ".my-notes.tmp"  # not a name the writers use: left alone
    mine.write_text("keep")
    opened(tmp_path, plan).close()
    assert not any(p.exists() for p in left) and mine.exists()


def test_a_second_journal_on_a_held_folder_is_refused(plan, tmp_path):
    j = Journal(tmp_path, definition(plan), command="pnp-twin sweep x --out y")
    with pytest.raises(FolderBusy) as e:
        opened(tmp_path, plan)
    message = str(e.value)
    assert f"in use by pid {os.getpid()} on " in message
    assert "(pnp-twin sweep x --out y) since 20" in message
    j.close()
    opened(tmp_path, plan).close()  # free again


def test_fresh_moves_the_old_study_aside_until_the_new_one_runs(plan, tmp_path):
    j = opened(tmp_path, plan)
    spec = plan.specs()[0]
    j.record(fake_row(spec))
    j.close()
    (tmp_path / "results.csv").write_text("old table")
    j = opened(tmp_path, plan, fresh=True)
    assert j.load(spec) is None and not (tmp_path / "results.csv").exists()
    assert (tmp_path / REPLACED / "results.csv").exists()
    j.restore()  # the new study failed before its first run: the old one comes back
    assert (tmp_path / "results.csv").read_text() == "old table"
    assert j.load(spec) is not None and not (tmp_path / REPLACED).exists()
    j.close()
    j = opened(tmp_path, plan, fresh=True)
    j.record(fake_row(plan.specs()[1]))
    j.started()  # the new study ran: the old one is deleted
    assert not (tmp_path / REPLACED).exists() and j.load(spec) is None
    j.close()


def test_a_killed_fresh_start_is_settled_on_the_next_open(plan, tmp_path):
    j = opened(tmp_path, plan)
    spec = plan.specs()[0]
    j.record(fake_row(spec))
    j.close()
    opened(tmp_path, plan, fresh=True).close()  # killed before its first run
    j = opened(tmp_path, plan)
    assert j.load(spec) is not None and not (tmp_path / REPLACED).exists()
    j.close()
    j = opened(tmp_path, plan, fresh=True)
    j.record(fake_row(plan.specs()[1]))
    j.close()  # killed after its first run, before the old study was deleted
    j = opened(tmp_path, plan)
    assert j.load(spec) is None and j.load(plan.specs()[1]) is not None
    assert not (tmp_path / REPLACED).exists()
    j.close()


def test_the_scenarios_sweep_section_only_counts_through_the_plan(plan, tmp_path):
    d = definition(plan)
    d["scenario"] = {**d["scenario"], "sweep": {"replications": 2}}
    Journal(tmp_path, d).close()
    d = definition(plan.with_replications(4))
    d["scenario"] = {**d["scenario"], "sweep": {"replications": 4}}
    Journal(tmp_path, d).close()  # more replications: the same study
    assert json.loads((tmp_path / "study.json").read_text())["replications"] == 4


def _torn_segment(folder: Path) -> None:
    """A new segment holding only a line cut short by a kill (no newline after it)."""
    runs = folder / "runs"
    runs.mkdir(exist_ok=True)
    number = max((int(p.name[:6]) for p in runs.glob("*.jsonl")), default=0) + 1
    (runs / f"{number:06d}.jsonl").write_bytes(b'{"run_id": "p000-SD-r00", "point": 0, "gri')


def test_a_killed_fresh_start_with_only_a_torn_line_keeps_the_old_study(plan, tmp_path):
    """A --fresh start killed while writing its first row never ran: the old study comes back
    (a segment holding only a cut-short line is no run)."""
    j = opened(tmp_path, plan)
    spec = plan.specs()[0]
    j.record(fake_row(spec))
    j.close()
    opened(tmp_path, plan, fresh=True).close()
    _torn_segment(tmp_path)  # the new study's first write, cut short
    j = opened(tmp_path, plan)
    assert j.load(spec) is not None and not (tmp_path / REPLACED).exists()
    j.close()


def test_a_folder_with_only_a_torn_line_opens_as_empty(plan, tmp_path):
    """runs/ with only a cut-short line and no study.json: nothing ran, so it is not refused
    as "has runs/"; the torn line is dropped and the run done."""
    _torn_segment(tmp_path)
    j = opened(tmp_path, plan)
    assert j.rows(plan.specs()) == [None] * len(plan.specs())
    j.close()


def test_a_store_from_a_newer_version_is_refused_in_one_line(plan, tmp_path):
    import sqlite3

    j = opened(tmp_path, plan)
    j.record(fake_row(plan.specs()[0]))
    j.close()
    db = sqlite3.connect(tmp_path / "runs" / "runs.sqlite")
    db.execute("PRAGMA user_version = 99")
    db.close()
    j = opened(tmp_path, plan)
    with pytest.raises(StudyError, match=r"runs.sqlite: was written by a newer pnp-twin") as e:
        j.rows(plan.specs())
    assert "\n" not in str(e.value)
    j.close()

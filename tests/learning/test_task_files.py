"""The task suite as versioned data files: each file loads to the task it always was."""

from __future__ import annotations

import pytest

from pnp_twin.learning.tasks import BY_ID, SUITE, VERSIONS, TaskError, get_task

# The suite's v1 as it was defined in code before it became data (commit 29096cf): a task's
# released version must never change, so its file must keep giving exactly this.
V1 = {
    "baseline": ("paper_baseline", ()),
    "high_load": ("paper_baseline", (("feeder.rate", 15.0), ("robots.arm_speed", 4.0))),
    "slow_robot": ("paper_baseline", (("robots.overrides", [{"robot": 1, "arm_speed": 1.5}]),)),
    "breakdowns": ("breakdowns", ()),
    "bursty": (
        "paper_baseline",
        (("feeder.arrival", "normal"), ("feeder.cv", 2.0), ("feeder.rate", 13.956)),
    ),
    "long_workspaces": ("paper_baseline", (("robots.workspace_length", 0.5),)),
}


@pytest.mark.parametrize("name", list(V1))
def test_v1_files_are_the_tasks_as_they_were(name):
    task = get_task(f"{name}-v1")
    assert (task.scenario, task.overrides) == V1[name]
    assert (task.termination, task.duration, task.warmup) == ("t_continue", 600.0, 60.0)
    assert (task.train_seeds, task.eval_seeds) == (range(1_000_000, 2**31), range(1000, 1020))
    assert task.metric == "gripping_rate" and task.id == f"{name}-v1"
    task.line()  # the line loads


def test_names_give_the_newest_version_and_ids_a_fixed_one():
    assert [t.name for t in SUITE] == list(V1)
    for t in VERSIONS:
        assert BY_ID[t.id] is t
        assert get_task(t.name).version >= t.version
    assert get_task("SLOW_ROBOT-v1") is get_task("slow_robot-v1")
    with pytest.raises(TaskError, match="or NAME-vN"):
        get_task("slow_robot-v9")
    assert get_task("slow_robot").to_json()["id"] == "slow_robot-v1"

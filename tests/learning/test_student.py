"""The lookahead's student: teacher labels, the fit, the checkpoint as a policy on both engines,
and the shipped students against their teacher on held-out labelled runs."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("torch")

from pnp_twin.learning.student import (  # noqa: E402
    FEATURES,
    RULE_ORDER,
    LabelJob,
    LineSpec,
    StudentArgs,
    Teacher,
    TeacherLabels,
    agreement,
    label_run,
    student_view,
    train_student,
)
from pnp_twin.policies.hdqn.checkpoint import load_agent, read_meta  # noqa: E402
from pnp_twin.policies.hdqn.features import size  # noqa: E402
from pnp_twin.policies.hdqn.numpy_forward import NumpyQ  # noqa: E402
from pnp_twin.policies.hdqn.policy import HDQNPolicy  # noqa: E402
from pnp_twin.policies.registry import make_policy  # noqa: E402
from pnp_twin.twin.loader import load_scenario, with_overrides  # noqa: E402
from pnp_twin.twin.run import simulate  # noqa: E402

TEACHER = "lookahead:K=4,H=1,base=SD"
SHIPPED = {
    # model: (line, teacher as evaluated, held-out agreement it must reach)
    "paper_baseline__student": (LineSpec(), "lookahead:K=128,H=1,base=auto", 0.6),
    "student_general": (LineSpec(), "lookahead:K=128,H=1,base=auto", 0.6),
}


def short(name: str = "paper_baseline", duration: float = 20.0):  # type: ignore[no-untyped-def]
    return with_overrides(load_scenario(name), {"duration": duration, "warmup": 0.0})


def test_teacher_acts_as_the_lookahead() -> None:
    """Recording labels changes nothing: the teacher's run is the lookahead's."""
    scenario = short()
    taught = simulate(scenario, Teacher(TEACHER), seed=3, engine="fast")
    plain = simulate(scenario, make_policy(TEACHER, 4), seed=3, engine="fast")
    assert taught.kpis["gripping_rate"] == plain.kpis["gripping_rate"]
    assert taught.parts["robot"].tolist() == plain.parts["robot"].tolist()


def test_labels_are_the_teachers_values_and_reproducible() -> None:
    job = LabelJob(LineSpec(), 0, 11, 20.0, TEACHER)
    a, b = label_run(job), label_run(job)
    assert len(a) > 20
    for f in TeacherLabels.fields():
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    assert a.obs.shape[1:] == (2, 8, 64) and a.values.shape[1] == len(RULE_ORDER)
    assert a.extra.shape[1] == size(FEATURES, len(RULE_ORDER), 4)
    assert (a.extra >= 0).all()  # the numpy forward's bound needs inputs >= 0
    np.testing.assert_array_equal(a.extra[:, :4].sum(axis=1), 1.0)  # the robot's one-hot
    # the teacher's part is a best one, and the rules that pick it are marked
    assert a.mask.any(axis=1).all()
    best = np.where(a.mask, a.values, -math.inf).max(axis=1)
    np.testing.assert_array_equal(best, a.values.max(axis=1))
    # ties go to the base rule's pick (SD here), as the lookahead breaks them
    sd = RULE_ORDER.index("SD")
    tie = a.values[:, sd] == a.values.max(axis=1)
    assert tie.any() and a.mask[tie, sd].all()


def test_trained_student_is_a_policy_on_both_engines(tmp_path) -> None:  # type: ignore[no-untyped-def]
    args = StudentArgs(
        lines=[LineSpec(), LineSpec("paper_baseline", ("robots.arm_speed=4",))],
        out=str(tmp_path),
        name="tiny",
        teacher=TEACHER,
        runs=2,
        duration=15.0,
        dagger=1,
        epochs=2,
    )
    folder = train_student(args)
    meta = read_meta(folder)
    assert meta["targets"] == "teacher" and meta["features"] == FEATURES
    assert (folder / "labels_1.npz").is_file()  # the DAgger round's labels
    assert "agreement" in (folder / "agreement.csv").read_text()
    scenario = short(duration=15.0)
    fast = simulate(scenario, HDQNPolicy.load(folder), seed=2, engine="fast")
    simpy = simulate(scenario, HDQNPolicy.load(folder), seed=2, engine="simpy")
    assert fast.kpis["gripping_rate"] == simpy.kpis["gripping_rate"]
    assert fast.parts["rule"].tolist() == simpy.parts["rule"].tolist()


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_shipped_student_follows_its_teacher(name: str) -> None:
    """Loads by name, runs the same on both engines through the numpy forward pass, and on a
    held-out labelled run (seed never used in training) picks the teacher's part on most
    decisions."""
    line, teacher, floor = SHIPPED[name]
    policy = make_policy(f"hdqn:{name}", 4)
    assert isinstance(policy, HDQNPolicy) and policy.features is not None
    scenario = short(duration=20.0)
    fast = simulate(scenario, policy, seed=1, engine="fast")
    assert policy._numpy is not None  # decisions through numpy, not torch
    simpy = simulate(scenario, make_policy(f"hdqn:{name}", 4), seed=1, engine="simpy")
    assert fast.parts["rule"].tolist() == simpy.parts["rule"].tolist()
    agent, meta = load_agent(name)
    held = label_run(LabelJob(line, 0, 9_999_001, 60.0, teacher, features=meta["features"]))
    view = student_view(held, meta["view"], load_scenario("paper_baseline"))
    assert agreement(agent, view)["agreement"] >= floor  # type: ignore[arg-type]
    # the numpy forward pass decides as torch does on these (real) observations
    want = agent.q_values(view.obs, view.extra).argmax(axis=1)
    for compiled in (False, True):  # the students decide through the compiled pass
        numpy_q = NumpyQ(agent.q, compiled=compiled)
        got = [numpy_q.greedy(view.obs[i : i + 1], view.extra[i : i + 1]) for i in range(len(view))]
        decided = [(g, int(w)) for g, w in zip(got, want, strict=True) if g is not None]
        assert len(decided) >= 0.9 * len(view) and all(g == w for g, w in decided)


def test_an_earlier_trainings_labels_join_the_fit(tmp_path) -> None:  # type: ignore[no-untyped-def]
    common = {"out": str(tmp_path), "teacher": TEACHER, "runs": 2, "duration": 10.0, "epochs": 1}
    first = train_student(StudentArgs(name="first", dagger=0, **common))  # type: ignore[arg-type]
    arm = LineSpec("paper_baseline", ("robots.arm_speed=4",))
    second = train_student(
        StudentArgs(name="second", lines=[arm], dagger=0, also=[str(first)], **common)  # type: ignore[arg-type]
    )
    own = TeacherLabels.load(second / "labels_0.npz")
    earlier = TeacherLabels.load(first / "labels_0.npz")
    fitted = read_meta(second)["counters"]["step"]
    assert fitted == len(own) + len(earlier) and len(earlier) > 0
    with pytest.raises(ValueError, match="holds no labels"):
        train_student(StudentArgs(name="third", also=[str(tmp_path / "none")], **common))  # type: ignore[arg-type]


def test_feature_comparison_scores_the_held_out_rows(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """bench/student_features.py: the rules' rows are the held-out labels' own agreement and
    regret; a folder without labels is one usage line, exit 2."""
    import subprocess
    import sys
    from pathlib import Path

    common = {"out": str(tmp_path), "teacher": TEACHER, "runs": 2, "duration": 10.0, "epochs": 1}
    folder = train_student(StudentArgs(name="f", dagger=0, **common))  # type: ignore[arg-type]
    script = str(Path(__file__).parents[2] / "bench" / "student_features.py")
    done = subprocess.run(
        [sys.executable, script, str(folder), "--epochs", "1"], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    rows = {ln[:28].strip(): ln[28:].split() for ln in done.stdout.splitlines()[2:]}
    assert list(rows) == [
        "SPT alone",
        "SD alone",
        "short continuation alone",
        "long continuation alone",
        "network, student-v2",
        "network, student-v3",
        "network, student-v4",
    ]
    held = TeacherLabels.load(folder / "held_0.npz")
    best = np.where(held.mask, held.values, -np.inf).max(axis=1)
    spt = RULE_ORDER.index("SPT")
    assert float(rows["SPT alone"][0]) == pytest.approx(held.mask[:, spt].mean(), abs=5e-4)
    regret = (best - held.values[:, spt]).mean()
    assert float(rows["SPT alone"][1]) == pytest.approx(regret, abs=5e-5)
    for agree, loss in rows.values():
        assert 0.0 <= float(agree) <= 1.0 and float(loss) >= 0.0
    bad = subprocess.run([sys.executable, script, str(tmp_path / "none")], capture_output=True)
    assert bad.returncode == 2 and b"no labels_0.npz" in bad.stderr.splitlines()[-1]

"""The lookahead controller as teacher, the HDQN as its fast student (imitation, DAgger).

The lookahead controller (:mod:`pnp_twin.policies.lookahead`) values, at each decision, every
distinct part the rules would pick: the parts gripped over K sampled futures when it takes
that part and every robot then follows the base rule. Those per-candidate values are rollout
labels of the kind :mod:`pnp_twin.learning.rollout` computes, measured by the planner itself.
This module

1. runs lines under a :class:`Teacher` (the lookahead controller, with 128 futures by
   default so that its values carry little noise, that also records, at each decision with
   two or more distinct candidates, the belt image, the decision features of
   :mod:`pnp_twin.policies.hdqn.features`, the value of each rule's pick and which rules pick
   the teacher's part); with a ``student`` the student acts (DAgger: the states the student
   visits, labelled by the teacher), the teacher with probability ``beta``;
2. fits the student's network (by default on the features alone, ``view = "none"``) to pick
   the teacher's part: cross-entropy of the softmax over the rules against the set of rules
   that pick it (several rules often pick the same part), each row weighted by how much the
   choice matters (the spread of its candidates' values, plus a floor), Adam on a one-cycle
   learning-rate schedule, :func:`fit`;
3. writes a checkpoint loadable as ``--policy hdqn:DIR`` (``targets = "teacher"``, the
   feature set in ``features``).

The labels of a run depend only on its scenario, seed, duration and the teacher's settings
(and the student's weights), so they are the same whatever the number of worker processes.
``bench/train_student.py`` is the command line.
"""

from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pnp_twin.learning.dqn_update import DQNAgent
from pnp_twin.learning.train_checkpoint import save_checkpoint
from pnp_twin.policies.hdqn.agent import AgentConfig
from pnp_twin.policies.hdqn.checkpoint import META
from pnp_twin.policies.hdqn.features import DecisionFeatures
from pnp_twin.policies.hdqn.features import size as feature_size
from pnp_twin.policies.hdqn.policy import HDQNPolicy
from pnp_twin.policies.hdqn.ranges import ranges_of
from pnp_twin.policies.lookahead import TRIED, Lookahead, better_base, parse
from pnp_twin.twin.camera import BeltCamera
from pnp_twin.twin.decision import Decision, RobotSpec
from pnp_twin.twin.loader import load_scenario, parse_sets, with_overrides
from pnp_twin.twin.run import simulate
from pnp_twin.twin.scenario import Scenario

log = logging.getLogger(__name__)

RULE_ORDER: tuple[str, ...] = TRIED
"""The student's actions: the lookahead's candidate rules, in its order."""
FEATURES = "student-v4"
"""The feature set new students see (``student-v4``: ``student-v2`` and, per rule's pick, two
continuations over the parts on the belt, a second's and one that counts their fate as the
teacher does; ``student-v3`` has only the first; ``student-v1`` lacks the second-pick
features)."""
CHANNELS = 2
EPISODE_SEED_BASE = 3_000_000
"""Label runs use seeds 3,000,000 + 1,000 line + i (disjoint from evaluation seeds 0..N-1,
the lookahead's tuning seeds 700,000+ and headroom's 600,000+)."""


@dataclass
class TeacherLabels:
    """Label rows: ``obs`` (n, C, H, W) uint8, ``extra`` (n, E) float32 features, ``values``
    (n, R) mean parts gripped per future for each rule's pick, ``mask`` (n, R) the rules that
    pick the teacher's part, ``line`` (n,) the index of the line the row came from."""

    obs: np.ndarray
    extra: np.ndarray
    values: np.ndarray
    mask: np.ndarray
    line: np.ndarray

    @classmethod
    def concat(cls, parts: list[TeacherLabels]) -> TeacherLabels:
        return cls(*(np.concatenate([getattr(p, f) for p in parts]) for f in cls.fields()))

    @staticmethod
    def fields() -> tuple[str, ...]:
        return ("obs", "extra", "values", "mask", "line")

    def __len__(self) -> int:
        return len(self.line)

    def take(self, rows: np.ndarray) -> TeacherLabels:
        return TeacherLabels(*(getattr(self, f)[rows] for f in self.fields()))

    def save(self, path: Path) -> None:
        np.savez_compressed(path, **{f: getattr(self, f) for f in self.fields()})

    @classmethod
    def load(cls, path: Path) -> TeacherLabels:
        with np.load(path) as z:
            return cls(*(z[f] for f in cls.fields()))


class Teacher(Lookahead):
    """The lookahead controller, recording its per-candidate values as label rows (see the
    module docstring). With ``student`` the student acts, the teacher with probability
    ``beta`` (drawn from its own stream, so the run's policy stream is the lookahead's)."""

    def __init__(
        self,
        spec: str,
        student: HDQNPolicy | None = None,
        beta: float = 0.0,
        line: int = 0,
        seed: int = 0,
        features: str = FEATURES,
    ) -> None:
        _, _, arg = spec.partition(":")
        super().__init__(parse(arg))
        self.features = DecisionFeatures(features, RULE_ORDER)
        self.student = student
        self.beta = beta
        self.line_index = line
        self.mixer = np.random.default_rng([seed, 7])
        self.camera: BeltCamera | None = None
        self.rows: list[tuple[np.ndarray, np.ndarray, list[float], list[bool]]] = []

    def reset(self, robots: list[RobotSpec], rng: np.random.Generator) -> None:
        super().reset(robots, rng)
        self.features.reset(robots)
        self.rows = []
        if self.student is not None:
            self.student.reset(robots, np.random.default_rng(0))

    def bind_run(self, scenario: Scenario, seed: int, duration: float) -> None:
        super().bind_run(scenario, seed, duration)
        self.features.reset(self.features.robots, float(scenario.feeder.rate))
        self.camera = BeltCamera(scenario, CHANNELS)
        if self.student is not None:
            self.student.bind_run(scenario, seed, duration)

    def attach(self, belt: Any) -> None:
        super().attach(belt)
        self.features.attach(belt)
        assert self.camera is not None, "bind_run before attach"
        self.camera.attach(belt)
        if self.student is not None:
            self.student.attach(belt)

    def choose(self, decision: Decision) -> int:
        if self._copy is None:
            self._copy = self._start()
        line = self._follow(decision)
        picks, candidates, totals, k = self.plan(decision, line)
        if totals is not None:
            futures = 1 if self.settings.oracle else self.settings.futures
            own = [picks[r] for r in RULE_ORDER]
            assert self.camera is not None
            self.rows.append(
                (
                    self.camera.belt(decision.time),
                    self.features.vector(decision, own),
                    [totals[candidates.index(p)] / futures for p in own],
                    [p == k for p in own],
                )
            )
            if self.student is not None and self.mixer.random() >= self.beta:
                k = self.student.choose(decision)
        self.last_rule = next((r for r in TRIED if picks[r] == k), self.base)
        self._answer.k, self._answer.last_rule = k, self.last_rule
        line.answer()
        self.decisions += 1
        return k

    def labels(self) -> TeacherLabels:
        n = len(self.rows)
        if not n:
            assert self.camera is not None
            e = feature_size(self.features.name, len(RULE_ORDER), len(self.features.robots))
            r = len(RULE_ORDER)
            return TeacherLabels(
                np.zeros((0, *self.camera.shape), np.uint8),
                np.zeros((0, e), np.float32),
                np.zeros((0, r), np.float32),
                np.zeros((0, r), bool),
                np.zeros(0, np.int64),
            )
        obs, extra, values, mask = zip(*self.rows, strict=True)
        return TeacherLabels(
            np.stack(obs),
            np.stack(extra),
            np.asarray(values, np.float32),
            np.asarray(mask, bool),
            np.full(n, self.line_index, np.int64),
        )


@dataclass(frozen=True)
class LineSpec:
    """One line of the training set: a scenario and ``--set`` overrides."""

    scenario: str = "paper_baseline"
    sets: tuple[str, ...] = ()

    def load(self) -> Scenario:
        return load_scenario(self.scenario, parse_sets(self.sets) or None)

    @property
    def label(self) -> str:
        return " ".join([self.scenario, *(f"--set {s}" for s in self.sets)])


def resolved(teacher: str, line: Scenario) -> str:
    """The teacher's name with ``base=auto`` replaced by the rule it takes on ``line`` as
    evaluated (the full scenario, not the shorter label runs)."""
    _, _, arg = teacher.partition(":")
    s = parse(arg)
    if s.base != "auto":
        return s.name
    return replace(s, base=better_base(line)).name


@dataclass(frozen=True)
class LabelJob:
    """One labelled run: the line (and its index in the training set), seed, feeding time,
    teacher, the student checkpoint acting in DAgger rounds (None: the teacher acts) and the
    teacher's share ``beta`` of those decisions, and the feature set recorded."""

    line: LineSpec
    index: int
    seed: int
    duration: float
    teacher: str
    student: str | None = None
    beta: float = 0.0
    features: str = FEATURES


def label_run(job: LabelJob) -> TeacherLabels:
    """One labelled run (worker entry point)."""
    torch.set_num_threads(1)
    line = job.line.load()
    teacher = resolved(job.teacher, line)
    scenario = with_overrides(line, {"warmup": 0.0, "duration": job.duration})
    pupil = HDQNPolicy.load(job.student) if job.student else None
    policy = Teacher(teacher, pupil, job.beta, job.index, job.seed, job.features)
    simulate(scenario, policy, seed=job.seed, engine="fast")
    return policy.labels()


@dataclass
class StudentArgs:
    """Everything one student training depends on (recorded in its checkpoint)."""

    lines: list[LineSpec] = field(default_factory=lambda: [LineSpec()])
    out: str = "runs/student"
    name: str = "student"
    teacher: str = "lookahead:K=128,H=1,base=auto"
    """The labelling lookahead: more futures than the controller's default give values
    with less noise (the student learns their mean, so it may beat a noisier teacher)."""
    seed: int = 1
    runs: int = 8
    """Labelled runs per line and round."""
    duration: float = 120.0
    """Feeding time of a labelled run, s."""
    dagger: int = 1
    """Rounds after the first in which the student acts and the teacher labels."""
    beta: float = 0.3
    """In DAgger rounds, probability that the teacher acts at a decision."""
    epochs: int = 30
    lr: float = 3e-3
    """Peak learning rate of the one-cycle schedule."""
    network: str = "student-wide"
    weight_decay: float = 1e-4
    batch_size: int = 256
    floor: float = 0.05
    """Row weight = spread of the candidates' values (parts per future) + floor."""
    holdout: float = 0.1
    """Share of each round's runs held out to measure agreement with the teacher."""
    view: str = "none"
    """What image the student sees: ``none`` (the decision features only), ``window`` (the
    deciding robot's workspace) or ``belt``."""
    features: str = FEATURES
    """The decision feature set (:data:`pnp_twin.policies.hdqn.features.SETS`)."""
    also: list[str] = field(default_factory=list)
    """Folders of earlier trainings (same feature set) whose labels join every fit here."""
    workers: int = 1


def windows(obs: np.ndarray, robots: np.ndarray, camera: BeltCamera) -> np.ndarray:
    """Each row's deciding robot's window of its whole-belt image (as the camera cuts it)."""
    c, h, w = obs.shape[1:]
    padded = np.zeros((len(obs), c, h, camera.padded), np.uint8)
    padded[:, :, :, :w] = obs
    width = camera.window_width
    out = np.empty((len(obs), c, h, width), np.uint8)
    for r, start in enumerate(camera.starts):
        rows = robots == r
        out[rows] = padded[rows][:, :, :, start : start + width]
    return out


def student_view(labels: TeacherLabels, view: str, scenario: Scenario) -> TeacherLabels:
    """The labels with the images the student sees (``view`` none, window or belt)."""
    if view == "belt":
        return labels
    if view == "none":
        obs = np.zeros((len(labels), 0, 1, 1), np.uint8)
        return TeacherLabels(obs, labels.extra, labels.values, labels.mask, labels.line)
    n = scenario.robots.count
    camera = BeltCamera(scenario, labels.obs.shape[1])
    obs = windows(labels.obs, labels.extra[:, :n].argmax(axis=1), camera)
    return TeacherLabels(obs, labels.extra, labels.values, labels.mask, labels.line)


def fit(labels: TeacherLabels, args: StudentArgs, n_robots: int) -> DQNAgent:
    """A fresh student network fitted to pick the teacher's part (seeded by the run)."""
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    k = labels.values.shape[1]
    config = AgentConfig(args.network, args.lr, 0.0, False)
    shape = tuple(labels.obs.shape[1:])
    agent = DQNAgent(config, shape, k, labels.extra.shape[1], "cpu")  # type: ignore[arg-type]
    net = agent.q
    opt = torch.optim.Adam(net.parameters(), lr=args.lr, weight_decay=args.weight_decay)
    obs = torch.as_tensor(labels.obs)
    extra = torch.as_tensor(labels.extra)
    mask = torch.as_tensor(labels.mask)
    spread = labels.values.max(axis=1) - labels.values.min(axis=1)
    weight = torch.as_tensor(spread + args.floor, dtype=torch.float32)
    weight = weight / weight.mean()
    steps = args.epochs * -(-len(labels) // args.batch_size)
    schedule = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=args.lr, total_steps=steps)
    net.train()
    for _ in range(args.epochs):
        order = torch.as_tensor(rng.permutation(len(labels)))
        for i in range(0, len(labels), args.batch_size):
            b = order[i : i + args.batch_size]
            logits = net(obs[b], extra[b])
            right = torch.logsumexp(logits.masked_fill(~mask[b], -1e9), dim=1)
            loss = (weight[b] * (torch.logsumexp(logits, dim=1) - right)).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            schedule.step()
    net.eval()
    agent.target.load_state_dict(net.state_dict())
    return agent


def agreement(agent: DQNAgent, labels: TeacherLabels) -> dict[str, float]:
    """On labelled rows: the share where the student's greedy rule picks the teacher's part,
    and the mean value (parts per future) its pick loses against the teacher's."""
    if not len(labels):
        return {"rows": 0, "agreement": float("nan"), "regret": float("nan")}
    with torch.no_grad():
        q = agent.q(torch.as_tensor(labels.obs), torch.as_tensor(labels.extra)).numpy()
    return {"rows": len(labels), **choice_scores(labels, q.argmax(axis=1))}


def choice_scores(labels: TeacherLabels, act: np.ndarray) -> dict[str, float]:
    """On labelled rows, choices ``act`` (a rule index per row): the share that picks the
    teacher's part (``agreement``), and the mean value lost against it (``regret``)."""
    rows = np.arange(len(labels))
    best = np.where(labels.mask, labels.values, -np.inf).max(axis=1)
    return {
        "agreement": float(labels.mask[rows, act].mean()),
        "regret": float((best - labels.values[rows, act]).mean()),
    }


def _jobs(args: StudentArgs, round_: int, student: str | None) -> list[LabelJob]:
    out = []
    for j, spec in enumerate(args.lines):
        for i in range(args.runs):
            seed = EPISODE_SEED_BASE + 1_000 * j + 100 * round_ + i + 10_000 * args.seed
            out.append(
                LabelJob(
                    spec, j, seed, args.duration, args.teacher, student, args.beta, args.features
                )
            )
    return out


def _label_all(jobs: list[LabelJob], workers: int) -> list[TeacherLabels]:
    if workers > 1:
        from pnp_twin.parallel import pool_map_ordered

        return list(pool_map_ordered(label_run, jobs, workers, ("pnp_twin.learning.student",)))
    return [label_run(j) for j in jobs]


def _split(parts: list[TeacherLabels], holdout: float, runs: int) -> tuple[list[int], list[int]]:
    """Run indices for training and for the held-out agreement (the last runs of each line)."""
    held = max(1, round(holdout * runs)) if holdout > 0 and runs > 1 else 0
    test = [i for i in range(len(parts)) if i % runs >= runs - held]
    return [i for i in range(len(parts)) if i not in test], test


def meta_for(args: StudentArgs, agent: DQNAgent, base: Scenario, counters: dict[str, Any]) -> dict:
    n = base.robots.count
    return {
        "name": args.name,
        "mode": "async",
        "view": args.view,
        "termination": "t_continue",
        "targets": "teacher",
        "features": args.features,
        "rules": list(RULE_ORDER),
        "n_robots": n,
        "scenario": base.model_dump(mode="json"),
        "train_args": {
            **asdict(args),
            "lines": [ln.label for ln in args.lines],
            "ranges": ranges_of([ln.load() for ln in args.lines]),
            "mode": "async",
        },
        "device": "cpu",
        "counters": counters,
    }


def earlier_labels(folder: Path, features: str, n_robots: int) -> tuple[TeacherLabels, ...]:
    """The training and held-out labels of every round an earlier training kept in
    ``folder``; ``ValueError`` when there are none or their features are not ``features``."""
    rounds = 0
    while (folder / f"labels_{rounds}.npz").is_file():
        rounds += 1
    if not rounds or not (folder / f"held_{rounds - 1}.npz").is_file():
        raise ValueError(f"also: {folder} holds no labels (labels_0.npz, held_0.npz, ...)")
    train = TeacherLabels.concat(
        [TeacherLabels.load(folder / f"labels_{r}.npz") for r in range(rounds)]
    )
    held = TeacherLabels.concat(
        [TeacherLabels.load(folder / f"held_{r}.npz") for r in range(rounds)]
    )
    width = feature_size(features, len(RULE_ORDER), n_robots)
    if train.extra.shape[1] != width:
        raise ValueError(
            f"also: {folder}'s labels have {train.extra.shape[1]} features; {features} with "
            f"{n_robots} robots has {width}"
        )
    return train, held


def train_student(args: StudentArgs) -> Path:
    """Label, fit, and for each DAgger round label the student's own runs and fit again;
    returns the checkpoint folder ``out/name``. Each round's labels are kept in
    ``labels_<round>.npz`` (a rerun reuses them) and ``agreement.csv`` gets a row per round."""
    torch.set_num_threads(1)
    folder = Path(args.out) / args.name
    folder.mkdir(parents=True, exist_ok=True)
    base = args.lines[0].load()
    earlier = [earlier_labels(Path(f), args.features, base.robots.count) for f in args.also]
    train_parts: list[TeacherLabels] = [tr for tr, _ in earlier]
    test_parts: list[TeacherLabels] = [te for _, te in earlier]
    student: str | None = None
    t0 = time.perf_counter()
    rows = []
    for round_ in range(args.dagger + 1):
        path = folder / f"labels_{round_}.npz"
        held_path = folder / f"held_{round_}.npz"
        if path.is_file() and held_path.is_file():
            train_parts.append(TeacherLabels.load(path))
            test_parts.append(TeacherLabels.load(held_path))
        else:
            parts = _label_all(_jobs(args, round_, student), args.workers)
            tr, te = _split(parts, args.holdout, args.runs)
            train_parts.append(TeacherLabels.concat([parts[i] for i in tr]))
            test_parts.append(TeacherLabels.concat([parts[i] for i in te]))
            train_parts[-1].save(path)
            test_parts[-1].save(held_path)
        following = folder / f"labels_{round_ + 1}.npz"
        if round_ < args.dagger and following.is_file() and (folder / META).is_file():
            continue  # a rerun with more rounds: the next round's labels are there already
        labels = student_view(TeacherLabels.concat(train_parts), args.view, base)
        agent = fit(labels, args, base.robots.count)
        held = student_view(TeacherLabels.concat(test_parts), args.view, base)
        score = agreement(agent, held)
        row = {"round": round_, "labels": len(labels), **score}
        row["wall_time"] = time.perf_counter() - t0
        rows.append(row)
        log.info("round %d: %s", round_, row)
        counters = {"step": len(labels), "episodes": len(labels), "wall_time": row["wall_time"]}
        save_checkpoint(folder, agent, meta_for(args, agent, base, counters), train_state=False)
        student = str(folder)
    done = folder / "agreement.csv"
    if done.is_file() and rows:  # rows of earlier rounds not refitted this time stay
        kept = done.read_text(encoding="utf-8").splitlines()[1 : 1 + int(rows[0]["round"])]
    else:
        kept = []
    with open(done, "w", encoding="utf-8") as f:
        f.write(",".join(rows[0]) + "\n")
        f.writelines(line + "\n" for line in kept)
        for r in rows:
            f.write(",".join(str(v) for v in r.values()) + "\n")
    return folder

"""Feature set ``student-any-v1``: ``student-v4``'s decision features, for any robot count
and order.

``student-v4`` holds a one-hot of the deciding robot and one block per robot, so its length
and meaning are tied to the line it was trained on. ``student-any-v1`` keeps every value
that describes the decision itself (per rule's pick, the line, the candidates one by one,
the upstream parts, both continuations: the same numbers, computed by the same compiled
passes) and replaces the per-robot blocks by what does not depend on how many robots there
are or how they are numbered:

- the deciding robot's own state (seconds until free, since its last grip, parts in its
  workspace) and its own parameters: arm speed, workspace length, grip + release time, side
  (upper, lower or over the belt), reach (0: none) and the share of part kinds it picks;
- its place in the line: the share of robots upstream, robots downstream and upstream, the
  robot count;
- the robots downstream pooled (mean and least seconds until free, mean arm speed, mean
  and most parts in their workspaces), the nearest one downstream on its own, and the
  robots upstream pooled (mean and least seconds until free, mean arm speed, mean parts).

A network on these scores the deciding robot's rules with the same weights wherever the
robot sits (per-robot scoring, shared weights), so one checkpoint runs on 2 to 16 robots.
"""

from __future__ import annotations

import numpy as np

from pnp_twin.twin.decision import RobotSpec
from pnp_twin.twin.fast.jit import compiled

OWN = 4 + 5 + 4
"""The deciding robot's state, its parameters and its place in the line."""
POOLS = 5 + 4 + 4
"""Downstream pooled, the nearest downstream robot, upstream pooled."""
PARAMS = 5
"""Static per-robot parameters (arm, workspace length, handling, side, reach, kinds)."""
MAX_ROBOTS = 16


def size(n_rules: int) -> int:
    """Length of a ``student-any-v1`` vector (no robot count in it)."""
    from pnp_twin.policies.hdqn import continuation
    from pnp_twin.policies.hdqn import features_compiled as fc

    tail = continuation.size(n_rules, True)
    return fc.PER_PICK * n_rules + 3 + fc.slots_size(n_rules) + tail + OWN + POOLS


def robot_params(robots: list[RobotSpec]) -> np.ndarray:
    """Each robot's own parameters, scaled to about [0, 1]: workspace length, grip + release
    time, side (0 upper, 0.5 over, 1 lower), reach (0: no limit) and the share of part kinds
    it picks (1: every kind). One row per robot (PARAMS columns)."""
    side = {"upper": 0.0, "over": 0.5, "lower": 1.0}
    rows = []
    for r in robots:
        kinds = (sum(r.picks) / len(r.picks)) if r.picks else 1.0
        rows.append(
            (
                min((r.workspace[1] - r.workspace[0]) / 0.5, 3.0),
                min((r.pick_time + r.place_time) / 0.1, 3.0),
                side.get(r.side, 0.0),
                min(r.reach / 1.0, 3.0),
                kinds,
            )
        )
    return np.asarray(rows, dtype=np.float64).reshape(len(robots), PARAMS)


@compiled()
def pool(
    out: np.ndarray,
    v4: np.ndarray,
    robot: int,
    n: int,
    n_rules: int,
    per_pick: int,
    per_robot: int,
    slots: int,
    params: np.ndarray,
) -> None:
    """``student-any-v1`` of one decision into ``out`` from its ``student-v4`` vector ``v4``
    (layout of :mod:`.features_compiled`: one-hot n, per pick, per robot, line 3, slots,
    robot places 3 n, then the continuation tail)."""
    out[:] = 0.0
    picks_at = n
    robots_at = picks_at + per_pick * n_rules
    line_at = robots_at + per_robot * n
    slots_at = line_at + 3
    tail_at = slots_at + slots + 3 * n
    j = 0
    for i in range(picks_at, robots_at):
        out[j] = v4[i]
        j += 1
    for i in range(line_at, slots_at + slots):
        out[j] = v4[i]
        j += 1
    for i in range(tail_at, v4.shape[0]):
        out[j] = v4[i]
        j += 1
    me = robots_at + per_robot * robot  # busy, since, arm / 4, load of the deciding robot
    for c in range(4):
        out[j + c] = v4[me + c]
    j += 4
    for c in range(params.shape[1]):
        out[j + c] = params[robot, c]
    j += params.shape[1]
    out[j] = robot / (n - 1.0) if n > 1 else 0.0
    out[j + 1] = (n - 1.0 - robot) / 8.0
    out[j + 2] = robot / 8.0
    out[j + 3] = n / 16.0
    j += 4
    # downstream: mean busy, least busy, mean arm, mean load, most load
    down = n - 1 - robot
    if down > 0:
        least = 1e9
        most = 0.0
        for r in range(robot + 1, n):
            at = robots_at + per_robot * r
            out[j] += v4[at] / down
            least = min(least, v4[at])
            out[j + 2] += v4[at + 2] / down
            out[j + 3] += v4[at + 3] / down
            most = max(most, v4[at + 3])
        out[j + 1] = least
        out[j + 4] = most
        at = robots_at + per_robot * (robot + 1)  # the nearest downstream robot
        out[j + 5] = v4[at]
        out[j + 6] = v4[at + 2]
        out[j + 7] = v4[at + 3]
        out[j + 8] = 1.0
    j += 9
    if robot > 0:  # upstream: mean busy, least busy, mean arm, mean load
        least = 1e9
        for r in range(robot):
            at = robots_at + per_robot * r
            out[j] += v4[at] / robot
            least = min(least, v4[at])
            out[j + 2] += v4[at + 2] / robot
            out[j + 3] += v4[at + 3] / robot
        out[j + 1] = least

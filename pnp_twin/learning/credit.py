"""Team credit for multi-agent training: picks of the robots an agent answers for."""

from __future__ import annotations

from collections.abc import Iterable

from pnp_twin.learning.envs.driver import EnvError


class TeamCredit:
    """Team picks credited to each robot's open option (the ``downstream``/``team`` rewards).

    After every epoch, :meth:`add` credits each robot with an open option with the picks
    completed during the epoch by the robots it answers for (itself and those downstream
    of it, or all); :meth:`take` returns a robot's count when its option ends and zeroes it.
    """

    def __init__(self, reward: str, n_robots: int) -> None:
        if reward not in ("downstream", "team"):
            raise EnvError(f"reward: '{reward}' is not a team reward; allowed downstream, team")
        first = (lambda r: r) if reward == "downstream" else (lambda r: 0)
        self.first = [first(r) for r in range(n_robots)]
        self.picks = [0] * n_robots

    def add(self, step_picks: list[int], open_robots: Iterable[int]) -> None:
        """Credit the picks of one epoch (per robot) to the robots whose option is open."""
        for r in open_robots:
            self.picks[r] += sum(step_picks[self.first[r] :])

    def take(self, robot: int) -> int:
        """The picks credited to ``robot``'s option that just ended (then zero)."""
        picks, self.picks[robot] = self.picks[robot], 0
        return picks

    def clear(self) -> None:
        """Forget every open option (a new episode)."""
        self.picks = [0] * len(self.picks)

"""Name -> policy: the names scenario files and the command line use (case-insensitive)."""

from __future__ import annotations

from collections.abc import Callable

from policies.base import RuleMix
from policies.rules import RULES
from twin.decision import Policy
from twin.errors import UserError

Factory = Callable[[str], Policy]

# Extra policy kinds by prefix, e.g. "hdqn:DIR"; filled by the modules that provide them.
PREFIXED: dict[str, Factory] = {}


class PolicyError(UserError):
    """An unknown policy name or a malformed mix; the message is one line."""


def allowed() -> str:
    names = ", ".join(RULES)
    extra = "".join(f", {p}:ARG" for p in PREFIXED)
    return f"{names}, a per-robot mix such as SPT,SPT,SPT,FIFO{extra}"


def make_policy(spec: str, n_robots: int | None = None) -> Policy:
    """A fresh policy for ``spec``: a rule name, a comma-separated mix, or ``prefix:arg``."""
    text = spec.strip()
    prefix, sep, arg = text.partition(":")
    if sep:
        _load_plugins()
        factory = PREFIXED.get(prefix.lower())
        if factory is None:
            raise PolicyError(f"policy: unknown kind '{prefix}'; allowed {allowed()}")
        return factory(arg)
    rules = [r.strip().upper() for r in text.split(",")]
    for r in rules:
        if r not in RULES:
            raise PolicyError(f"policy: '{r or text}' is not a rule; allowed {allowed()}")
    if n_robots is not None and len(rules) not in (1, n_robots):
        raise PolicyError(
            f"policy: the mix '{text}' names {len(rules)} rules for {n_robots} robots; "
            f"give one rule or one per robot"
        )
    return RuleMix(rules)


def _load_plugins() -> None:
    try:  # the learned policy registers "hdqn"; it needs the learn extra
        import policies.hdqn_policy  # noqa: F401
    except ImportError:
        pass

"""Name -> policy: the names scenario files and the command line use (case-insensitive)."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Sequence

from pnp_twin.policies.base import RuleMix
from pnp_twin.policies.rules import NAMED_RULES as RULES
from pnp_twin.twin.decision import Policy
from pnp_twin.twin.errors import UserError, excerpt

Factory = Callable[[str], Policy]

# Extra policy kinds by prefix, e.g. "hdqn:DIR": "module:function" entries, imported only
# when a spec names them (the learned policy needs torch, the ``learn`` extra).
PREFIXED: dict[str, str] = {
    "hdqn": "pnp_twin.policies.hdqn.policy:from_spec",
    "sb3": "pnp_twin.policies.sb3_policy:from_spec",
    "marl": "pnp_twin.policies.marl_policy:from_spec",
    "lookahead": "pnp_twin.policies.lookahead:from_spec",
    "py": "pnp_twin.policies.user_policy:from_spec",
    "share": "pnp_twin.policies.balancing:share_policy",
    "lane": "pnp_twin.policies.balancing:lane_policy",
    "list": "pnp_twin.policies.balancing:list_policy",
}


class PolicyError(UserError):
    """An unknown policy name or a malformed mix; the message is one line."""


def rule_names(names: Sequence[str]) -> tuple[str, ...]:
    """Upper-cased rule names, each a known rule: the one check of rule names (callers add
    their field to the message). Raises ``ValueError`` naming the bad name and the rules."""
    out = tuple(str(r).strip().upper() for r in names)
    if not out:
        raise ValueError(f"empty; give at least one of {', '.join(RULES)}")
    for r in out:
        if r not in RULES:
            raise ValueError(f"{excerpt(r, 40)} is not a rule; allowed {', '.join(RULES)}")
    return out


def allowed() -> str:
    names = ", ".join(RULES)
    extra = "".join(f", {p}:ARG" for p in PREFIXED)
    return f"{names}, a per-robot mix such as SPT,SPT,SPT,FIFO{extra}"


def make_policy(spec: str, n_robots: int | None = None) -> Policy:
    """A fresh policy for ``spec``: a rule name, a comma-separated mix, or ``prefix:arg``."""
    text = spec.strip()
    prefix, sep, arg = text.partition(":")
    if sep or prefix.lower() == "lookahead":  # ``lookahead`` alone: its defaults
        entry = PREFIXED.get(prefix.lower())
        if entry is None:
            raise PolicyError(f"policy: unknown kind {excerpt(prefix, 40)}; allowed {allowed()}")
        return _load(prefix.lower(), entry)(arg)
    try:
        rules = list(rule_names(text.split(",")))
    except ValueError as e:
        extra = "".join(f", {p}:ARG" for p in PREFIXED)
        raise PolicyError(f"policy: {e}, a per-robot mix such as SPT,SPT,SPT,FIFO{extra}") from None
    if n_robots is not None and len(rules) not in (1, n_robots):
        raise PolicyError(
            f"policy: the mix '{text}' names {len(rules)} rules for {n_robots} robots; "
            f"give one rule or one per robot"
        )
    return RuleMix(rules)


def _load(prefix: str, entry: str) -> Factory:
    """The factory a registry entry names, imported now; a missing extra is one line."""
    module, _, attr = entry.partition(":")
    try:
        factory: Factory = getattr(importlib.import_module(module), attr)
    except ImportError as e:
        raise PolicyError(
            f"policy: {prefix}: needs the learn extra ({e.name} is missing); "
            "install it: pip install 'pnp-twin[learn]'"
        ) from None
    return factory

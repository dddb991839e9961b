"""A policy of the user's own code: ``py:FILE.py:FACTORY`` or ``py:package.module:FACTORY``.

Whatever takes ``--policy`` (``run``, ``sweep``, ``size``, ``evaluate``, ``task score``, ...)
takes it: ``FACTORY`` is a callable in that file or module that returns a fresh policy (an
object with ``reset(robots, rng)`` and ``choose(decision) -> int``, see
:class:`pnp_twin.twin.decision.Policy`); a class is such a callable. Text after a further
``:`` is handed to the factory as its one argument (``py:mine.py:make:greedy``), so one
factory can build several policies. Worker processes build their own copy from the same spec.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import sys
from pathlib import Path
from types import ModuleType

from pnp_twin.twin.decision import Policy
from pnp_twin.twin.errors import UserError

FORMAT = "py:FILE.py:FACTORY[:ARG] or py:package.module:FACTORY[:ARG]"


class UserPolicyError(UserError):
    """A ``py:`` spec that names no loadable factory or yields no policy; one line."""


def from_spec(arg: str) -> Policy:
    """The policy ``FACTORY`` (``FACTORY(ARG)`` when an argument is given) returns."""
    target, _, rest = arg.partition(":")
    name, sep, factory_arg = rest.partition(":")
    if not target.strip() or not name.strip():
        raise UserPolicyError(f"policy: py:{arg}: give {FORMAT}")
    module = _module(target.strip(), arg)
    factory = getattr(module, name.strip(), None)
    if not callable(factory):
        raise UserPolicyError(
            f"policy: py:{arg}: '{target}' has no callable '{name}'; give {FORMAT}"
        )
    try:
        policy = factory(factory_arg) if sep else factory()
    except Exception as e:  # the user's code: one line naming it, not their traceback
        raise UserPolicyError(
            f"policy: py:{arg}: {name}() raised {type(e).__name__}: {e}"
        ) from None
    missing = [m for m in ("reset", "choose") if not callable(getattr(policy, m, None))]
    if missing:
        raise UserPolicyError(
            f"policy: py:{arg}: {name}() returned {type(policy).__name__}, which has no "
            f"{' or '.join(missing)}(); a policy needs reset(robots, rng) and choose(decision)"
        )
    return policy  # type: ignore[no-any-return]


def _module(target: str, arg: str) -> ModuleType:
    """A ``.py`` file by its path, else a module by its dotted name."""
    if target.endswith(".py"):
        return _file_module(Path(target), arg)
    try:
        return importlib.import_module(target)
    except ImportError as e:
        raise UserPolicyError(
            f"policy: py:{arg}: cannot import '{target}' ({e}); give {FORMAT}"
        ) from None


def _file_module(path: Path, arg: str) -> ModuleType:
    if not path.is_file():
        raise UserPolicyError(f"policy: py:{arg}: '{path}' is not a file; give {FORMAT}")
    key = "pnp_twin_user_policy_" + hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:16]
    if key in sys.modules:
        return sys.modules[key]
    spec = importlib.util.spec_from_file_location(key, path)
    if spec is None or spec.loader is None:
        raise UserPolicyError(f"policy: py:{arg}: '{path}' cannot be loaded as Python")
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except Exception as e:
        raise UserPolicyError(
            f"policy: py:{arg}: loading '{path}' raised {type(e).__name__}: {e}"
        ) from None
    sys.modules[key] = module
    return module

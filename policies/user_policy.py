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
import sys
from pathlib import Path
from types import ModuleType

from pnp_twin.policies.user_guard import GuardedPolicy
from pnp_twin.twin.decision import Policy
from pnp_twin.twin.errors import UserError, clip
from pnp_twin.twin.inputs import POLICY_BYTES, read_user_text

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
    except KeyboardInterrupt:
        raise
    except BaseException as e:  # noqa: BLE001 (SystemExit too: exit codes stay ours)  # the user's code: one line naming it, not their traceback
        raise UserPolicyError(
            f"policy: py:{arg}: {name}() raised {type(e).__name__}: {e}"
        ) from None
    missing = [m for m in ("reset", "choose") if not callable(getattr(policy, m, None))]
    if missing:
        raise UserPolicyError(
            f"policy: py:{arg}: {name}() returned {type(policy).__name__}, which has no "
            f"{' or '.join(missing)}(); a policy needs reset(robots, rng) and choose(decision)"
        )
    return GuardedPolicy(policy, f"py:{arg}")  # type: ignore[return-value]


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
    """The module of a policy file, read through the input guard (a regular UTF-8 file of
    at most :data:`POLICY_BYTES`) and run once per process."""
    if not path.exists():
        raise UserPolicyError(f"policy: py:{arg}: '{path}' is not a file; give {FORMAT}")
    label = f"policy: py:{arg}"
    source = read_user_text(path, label, POLICY_BYTES, UserPolicyError)
    key = "pnp_twin_user_policy_" + hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:16]
    if key in sys.modules:
        return sys.modules[key]
    module = ModuleType(key)
    module.__file__ = str(path)
    sys.modules[key] = module  # during its run too: dataclasses and pickling look it up
    try:
        exec(compile(source, str(path), "exec"), module.__dict__)  # noqa: S102 (the user's own policy)
    except BaseException as e:  # noqa: BLE001 (SystemExit too: exit codes stay ours)
        del sys.modules[key]
        if isinstance(e, KeyboardInterrupt):
            raise
        raise UserPolicyError(
            f"policy: py:{arg}: loading '{path}' raised {type(e).__name__}: {clip(str(e))}"
        ) from None
    return module

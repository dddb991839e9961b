"""A user's ``py:`` policy as a boundary: whatever it answers or raises becomes one line.

:class:`GuardedPolicy` wraps the object a ``py:`` factory returns. Each ``choose`` answer is
checked (an index of a candidate, a numpy integer too, or None for "no pick now"; a bool, a
float, a string, a list, NaN or an index outside the candidates is refused); anything the
user's code raises (``SystemExit`` included, so exit codes stay ours) becomes a
:class:`~pnp_twin.policies.user_policy.UserPolicyError` naming the policy, the decision and
the value; and a decision that takes longer than the limit stops the run with one line.

The limit is :data:`DEFAULT_TIMEOUT` seconds, or the ``PNP_TWIN_DECISION_TIMEOUT``
environment variable (the command line's ``--decision-timeout`` sets it, so worker processes
see it too); 0 turns it off. In the main thread it is kept by ``SIGALRM``; elsewhere (a Ray
worker's thread) by a timer that raises in the deciding thread.
"""

from __future__ import annotations

import ctypes
import math
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from numbers import Integral
from typing import Any

from pnp_twin.twin.decision import Decision
from pnp_twin.twin.errors import UserError, excerpt

DEFAULT_TIMEOUT = 10.0
TIMEOUT_ENV = "PNP_TWIN_DECISION_TIMEOUT"


class PolicyAnswerError(UserError):
    """A user policy's answer, exception or delay, in one line."""


class DecisionTimeout(BaseException):
    """Raised inside a decision that ran past the limit (a BaseException: the user's own
    ``except Exception`` cannot swallow it)."""


def decision_timeout() -> float:
    """The limit in seconds per decision (0: none), from the environment."""
    raw = os.environ.get(TIMEOUT_ENV, "").strip()
    if not raw:
        return DEFAULT_TIMEOUT
    try:
        value = float(raw)
    except ValueError:
        value = -1.0
    if not math.isfinite(value) or value < 0:
        raise PolicyAnswerError(
            f"{TIMEOUT_ENV}: {excerpt(raw)} is not allowed; give seconds >= 0 (0: no limit)"
        )
    return value


@contextmanager
def _limit(seconds: float) -> Iterator[None]:
    """Raise :class:`DecisionTimeout` in this thread once ``seconds`` have passed."""
    if seconds <= 0:
        yield
        return
    if threading.current_thread() is threading.main_thread():
        with _alarm(seconds):
            yield
        return
    ident = threading.get_ident()
    timer = threading.Timer(
        seconds,
        lambda: ctypes.pythonapi.PyThreadState_SetAsyncExc(
            ctypes.c_ulong(ident), ctypes.py_object(DecisionTimeout)
        ),
    )
    timer.start()
    try:
        yield
    finally:
        timer.cancel()


@contextmanager
def _alarm(seconds: float) -> Iterator[None]:
    """``SIGALRM`` after ``seconds``, keeping an outer alarm (a caller's own time limit):
    it still rings at its time, and is set again for what is left of it afterwards."""
    outer, _ = signal.getitimer(signal.ITIMER_REAL)
    start = time.monotonic()

    def ring(signum: int, frame: Any) -> None:
        if time.monotonic() - start >= seconds - 1e-3:
            raise DecisionTimeout
        if callable(previous):  # the outer alarm's time came first
            previous(signum, frame)

    previous = signal.signal(signal.SIGALRM, ring)
    signal.setitimer(signal.ITIMER_REAL, min(seconds, outer) if outer > 0 else seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        if outer > 0:
            signal.setitimer(signal.ITIMER_REAL, max(outer - (time.monotonic() - start), 1e-3))


def _where(decision: Decision) -> str:
    return (
        f"the decision of robot {decision.robot + 1} at t={decision.time:.3f} s "
        f"({len(decision)} candidate{'' if len(decision) == 1 else 's'})"
    )


def checked_answer(answer: Any, decision: Decision, name: str) -> int | None:
    """``answer`` as a candidate index (or None), else one line saying what was wrong."""
    if answer is None:
        return None
    if isinstance(answer, Integral) and not isinstance(answer, bool):
        k = int(answer)
        if 0 <= k < len(decision):
            return k
    allowed = f"an index 0..{len(decision) - 1} of the candidates, or None for no pick now"
    raise PolicyAnswerError(
        f"policy {name}: choose() answered {excerpt(answer)} ({type(answer).__name__}) to "
        f"{_where(decision)}; give {allowed}"
    )


class GuardedPolicy:
    """``inner`` with every call checked; attributes (``last_rule`` ...) read through."""

    def __init__(self, inner: Any, name: str) -> None:
        self._inner = inner
        self._name = name
        self._timeout = decision_timeout()

    @property
    def name(self) -> str:
        """The user's policy's own name (its ``name``, else its class's)."""
        return str(getattr(self._inner, "name", type(self._inner).__name__))

    def __getattr__(self, attr: str) -> Any:
        if attr.startswith("_"):  # not set yet (a copy being built): no recursion
            raise AttributeError(attr)
        value = getattr(self._inner, attr)
        if attr in ("reset", "attach", "bind_run", "fixed_rules") and callable(value):
            return self._guarded(value, attr)
        return value

    def _guarded(self, method: Callable[..., Any], what: str) -> Callable[..., Any]:
        def call(*args: Any, **kwargs: Any) -> Any:
            try:
                return method(*args, **kwargs)
            except (KeyboardInterrupt, UserError):
                raise
            except BaseException as e:  # noqa: BLE001 (the user's code: one line, our exit code)
                raise PolicyAnswerError(
                    f"policy {self._name}: {what}() raised {type(e).__name__}: {excerpt(str(e))}"
                ) from None

        return call

    def choose(self, decision: Decision) -> int | None:
        try:
            with _limit(self._timeout):
                answer = self._inner.choose(decision)
        except DecisionTimeout:
            raise PolicyAnswerError(
                f"policy {self._name}: choose() took longer than {self._timeout:g} s on "
                f"{_where(decision)}; make it faster or raise --decision-timeout"
            ) from None
        except (KeyboardInterrupt, UserError):
            raise
        except BaseException as e:  # noqa: BLE001 (SystemExit too: exit codes stay ours)
            raise PolicyAnswerError(
                f"policy {self._name}: choose() raised {type(e).__name__}: "
                f"{excerpt(str(e))} on {_where(decision)}"
            ) from None
        return checked_answer(answer, decision, self._name)

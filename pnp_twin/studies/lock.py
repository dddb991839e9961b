"""The lock of a study folder: one study process writes into a folder at a time.

The lock is an OS file lock (``filelock``) on ``DIR/.study.lock``; the kernel releases it
when its holder ends, even after a SIGKILL, so a stale lock never blocks a resume. Beside
it, ``DIR/.study.lock.json`` says who holds it (pid, host, command, since when), so a second
process is refused at once with one line that names the holder.
"""

from __future__ import annotations

import json
import logging
import os
import socket
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from filelock import FileLock, Timeout

from pnp_twin.studies.plan import StudyError
from pnp_twin.twin.output import write_json

log = logging.getLogger(__name__)

LOCK = ".study.lock"
HOLDER = ".study.lock.json"


class FolderBusy(StudyError):
    """The study folder is held by another process; the message names it, in one line."""


def holder_text(info: Any) -> str:
    """``pid 123 on host (pnp-twin sweep ...) since 2026-...`` from a holder mapping."""
    if not isinstance(info, dict):
        return "another process"
    command = str(info.get("command") or "").strip()
    if len(command) > 80:
        command = command[:77] + "..."
    where = f"pid {info.get('pid', '?')} on {info.get('host', '?')}"
    return where + (f" ({command})" if command else "") + f" since {info.get('since', '?')}"


class StudyLock:
    """The lock of one study folder; :meth:`acquire` never waits."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self.info_path = self.folder / HOLDER
        self._lock = FileLock(self.folder / LOCK, timeout=0)

    @property
    def held(self) -> bool:
        return self._lock.is_locked

    def holder(self) -> dict[str, Any] | None:
        """Who holds the lock, as written by its holder (None if unknown)."""
        try:
            info = json.loads(self.info_path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        return info if isinstance(info, dict) else None

    def acquire(self, command: str = "") -> None:
        """Take the lock, or raise :class:`FolderBusy` naming its holder."""
        self.folder.mkdir(parents=True, exist_ok=True)
        try:
            self._lock.acquire(timeout=0)
        except Timeout:
            raise FolderBusy(
                f"--out {self.folder}: in use by {holder_text(self.holder())}; wait for it "
                "to finish or choose another folder"
            ) from None
        info = {
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "command": command,
            "since": datetime.now(UTC).isoformat(timespec="seconds"),
        }
        write_json(info, self.info_path)
        log.debug("locked %s", self.folder)

    def release(self) -> None:
        """Let the lock go (a no-op if not held)."""
        if not self._lock.is_locked:
            return
        self.info_path.unlink(missing_ok=True)
        self._lock.release(force=True)
        log.debug("unlocked %s", self.folder)

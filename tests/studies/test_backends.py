"""Where runs execute: in-process, the local pool, Ray; workers end with their caller."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from pnp_twin.parallel import ParallelError, check_reachable, pool_map, process_alive
from pnp_twin.studies.backends import run_specs
from pnp_twin.studies.plan import StudyError, build_plan
from pnp_twin.twin import load_scenario, with_overrides

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def specs():
    line = with_overrides(load_scenario("paper_baseline"), {"duration": 20, "warmup": 2})
    plan = build_plan(line, grid={"feeder.rate": [8.0, 12.0]}, policies=["SD", "FIFO"])
    return plan.specs()[:6]


def collect(specs, **kw):
    rows = []
    run_specs(specs, rows.append, **kw)
    return {r["run_id"]: {k: v for k, v in r.items() if k != "wall_time"} for r in rows}


def test_pool_rows_equal_in_process_rows(specs):
    serial = collect(specs, workers=1)
    assert list(serial) == [s.run_id for s in specs]  # in-process: in order
    assert collect(specs, workers=2) == serial  # any order, same rows


def test_bad_backend_or_workers_is_one_line(specs):
    with pytest.raises(StudyError, match="--backend: 'dask' is not allowed"):
        run_specs(specs, print, backend="dask")
    with pytest.raises(StudyError, match="--workers: 0 is not allowed"):
        run_specs(specs, print, workers=0)


def fail_on_three(x: int) -> int:
    if x == 3:
        raise ValueError("three")
    return x


def test_a_failing_item_stops_the_pool_with_its_error():
    seen: list[int] = []
    with pytest.raises(ValueError, match="three"):
        pool_map(fail_on_three, range(8), seen.append, 2)
    assert 3 not in seen


def test_process_alive_sees_zombies_as_dead():
    assert process_alive(os.getpid())
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    deadline = time.monotonic() + 10
    while process_alive(child.pid) and time.monotonic() < deadline:
        time.sleep(0.05)  # exited but not yet reaped: a zombie
    assert not process_alive(child.pid)
    child.wait()
    assert not process_alive(child.pid)


def session_members(sid: int) -> list[int]:
    """Live processes of session ``sid`` (Linux /proc)."""
    out = []
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            fields = Path(f"/proc/{d}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] not in ("Z", "X"):
            out.append(int(d))
    return out


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_workers_end_when_their_caller_is_killed(tmp_path):
    script = tmp_path / "caller.py"
    script.write_text(
        textwrap.dedent(
            """
            import sys, time
            from pnp_twin.parallel import pool_map

            def nap(x):
                print("started", flush=True)
                time.sleep(60)
                return x

            if __name__ == "__main__":
                sys.path.insert(0, sys.argv[1])
                pool_map(nap, range(4), print, 2)
            """
        )
    )
    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{tmp_path}"}
    caller = subprocess.Popen(
        [sys.executable, str(script), str(tmp_path)],
        start_new_session=True,
        stdout=subprocess.PIPE,
        env=env,
    )
    try:
        assert caller.stdout is not None
        caller.stdout.readline()  # a worker is running
        assert len(session_members(caller.pid)) >= 4  # caller, forkserver, tracker, workers
        caller.send_signal(signal.SIGKILL)
        caller.wait()
        deadline = time.monotonic() + 10
        while session_members(caller.pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert session_members(caller.pid) == []
        assert caller.stdout.read().count(b"started") <= 1  # EOF: nobody holds the pipe
    finally:
        for pid in session_members(caller.pid):
            os.kill(pid, signal.SIGKILL)


def test_an_unreachable_ray_address_fails_fast_in_one_line(specs):
    started = time.monotonic()
    with pytest.raises(ParallelError, match=r"--address 127.0.0.1:1: cannot connect to Ray"):
        check_reachable("127.0.0.1:1")
    with pytest.raises(ParallelError, match="cannot connect to Ray"):
        check_reachable("ray://127.0.0.1:1")
    check_reachable("auto")  # Ray resolves names like this itself
    assert time.monotonic() - started < 5


def test_ray_backend_refuses_an_unreachable_address(specs):
    pytest.importorskip("ray")
    started = time.monotonic()
    with pytest.raises(ParallelError, match=r"^--address 127.0.0.1:1: cannot connect to Ray"):
        run_specs(specs, print, backend="ray", workers=2, address="127.0.0.1:1")
    assert time.monotonic() - started < 30


def test_one_executor_keeps_its_pool_and_gives_the_same_rows(specs, monkeypatch):
    """Executor: short batches in-process (a pool's trips would cost more), longer ones in
    one pool kept across batches, in chunks; the rows are the same either way."""
    from pnp_twin.studies import backends
    from pnp_twin.studies.backends import Executor, chunks

    assert [len(c) for c in chunks(list(range(20)), 2)] == [5, 5, 5, 5]
    assert [len(c) for c in chunks(list(range(3)), 2)] == [1, 1, 1]
    serial = collect(specs, workers=1)
    with Executor("local", 2) as ex:  # runs of a few ms: never worth a pool
        rows: list = []
        ex.run(specs, rows.append)
        assert ex._pool is None
    assert {r["run_id"]: {k: v for k, v in r.items() if k != "wall_time"} for r in rows} == serial
    monkeypatch.setattr(backends, "POOL_WORTH", 0.0)  # every batch worth a pool
    with Executor("local", 2) as ex:
        first: list = []
        ex.run(specs[:3], first.append)
        pool = ex._pool
        second: list = []
        ex.run(specs[3:], second.append)
        assert pool is not None and ex._pool is pool  # one pool for both batches
    both = {r["run_id"]: {k: v for k, v in r.items() if k != "wall_time"} for r in first + second}
    assert both == serial

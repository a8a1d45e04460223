"""The executor seam (rheo_shaping.parallel): serial, a local process pool and a real Dask
cluster (a LocalCluster: scheduler and worker processes on this machine) give the same
results in the same order; bad specs are refused by name."""
from __future__ import annotations

import os

import pytest

from rheo_shaping.planning.choose_d import run_d
from rheo_shaping.parallel import SerialExecutor, executor_from_spec, executor_workers, run_tasks
from rheo_shaping.params.cell import CellParams


def _scaled(shared: dict, item: int) -> tuple[int, int, int]:
    return item, item * shared["factor"], os.getpid()


def _fails(shared, item):
    if item == 3:
        raise ValueError(f"item {item} is bad")
    return item


def test_serial_and_local_pool_agree_in_order_and_progress_counts_every_item():
    items = list(range(23))
    done: list[int] = []
    serial = run_tasks(SerialExecutor(), _scaled, {"factor": 3}, items, done.append)
    assert [r[:2] for r in serial] == [(i, 3 * i) for i in items]
    assert sum(done) == 23 and set(r[2] for r in serial) == {os.getpid()}
    done.clear()
    with executor_from_spec("local:2") as pool:
        assert executor_workers(pool) == 2
        pooled = run_tasks(pool, _scaled, {"factor": 3}, items, done.append)
    assert [r[:2] for r in pooled] == [r[:2] for r in serial]
    assert sum(done) == 23
    assert os.getpid() not in {r[2] for r in pooled}          # it really ran elsewhere


def test_a_task_error_reaches_the_caller():
    with executor_from_spec("local:2") as pool:
        with pytest.raises(ValueError, match="item 3 is bad"):
            run_tasks(pool, _fails, None, range(6))


@pytest.mark.parametrize("spec, says", [
    ("locale", "is not an executor"), ("local:0", "N >= 1"), ("local:x", "N >= 1"),
    ("dask://nohost", "dask://HOST:PORT"), ("tcp://1.2.3.4:1", "is not an executor")])
def test_bad_specs_are_refused_by_name(spec, says):
    with pytest.raises(ValueError, match=says) as err:
        with executor_from_spec(spec):
            pass
    assert repr(spec) in str(err.value)


def test_no_scheduler_at_the_address_is_a_clear_error(monkeypatch):
    import socket
    import rheo_shaping.parallel
    monkeypatch.setattr(rheo_shaping.parallel, "CONNECT_TIMEOUT_S", 2.0)   # the same refusal
    with socket.socket() as s:                     # a port with nothing listening
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(ValueError, match="no Dask scheduler answers"):
        with executor_from_spec(f"dask://127.0.0.1:{port}"):
            pass


def test_dask_local_cluster_runs_the_d_sweep_like_a_local_run():
    distributed = pytest.importorskip("distributed")
    params = CellParams()
    ds = [0.012, 0.016]
    local = run_tasks(None, run_d, params, ds)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None, host="127.0.0.1") as cluster:
        address = cluster.scheduler_address.removeprefix("tcp://")
        with executor_from_spec(f"dask://{address}") as ex:
            assert executor_workers(ex) == 2
            remote = run_tasks(ex, run_d, params, ds)
    assert [r.d for r in remote] == ds
    for a, b in zip(local, remote):       # the same deterministic model on other processes
        assert b.F_max == a.F_max and b.delta == a.delta and not b.error

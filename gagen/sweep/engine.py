"""Running a sweep on Dask ``distributed``: every unfinished chunk a task, each result written the moment
it reaches the client.

The cluster is a ``LocalCluster`` of ``workers`` processes with one thread each (the C kernels and the
iLQR loop are single-threaded; separate processes keep one worker's crash from taking the others, and
keep the BLAS of the stacked SVD to one thread per core), or, with ``scheduler``, an existing one at
that address (``dask scheduler`` on one machine, ``dask worker ADDRESS`` on each: every worker needs
gagen, and builds the system's generated module on first use where ``gagen.modules`` puts it; the
output folder only needs to exist where this client runs, since the client writes the files).

Why the client writes: a chunk is finished when its file exists, and the file is written (atomically,
``gagen.sweep.store``) as soon as the chunk's rows arrive, so a worker killed afterwards loses nothing;
a worker killed while computing loses only its running chunk, which the scheduler hands to another
worker (its own retry of tasks lost with a worker). If the whole run stops (Ctrl-C, a crash, a task
that raised), a re-run into the same folder skips the finished chunks and computes the rest.

The progress bar is tqdm's, counting chunks written (it starts at the chunks already finished): what
resuming is about; dask's own ``progress`` counts tasks and knows nothing of the files.
"""

from __future__ import annotations

import contextlib
import logging
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from gagen.extras import check
from gagen.sweep.problems import Sweep, compute_chunk, prepare
from gagen.sweep.store import ChunkStore, SweepError

check(("dask", "distributed", "tqdm"), "gagen.sweep")  # the sweep extra, named before any work

if TYPE_CHECKING:
    from distributed import Client


@dataclass
class Outcome:
    """What one run did: ``computed`` the chunk indices it wrote (in the order they finished), ``rows``
    their rows, ``skipped`` the number already finished, ``failed`` index -> error of chunks whose task
    raised, ``seconds`` the wall time of the computing part (cluster start and the workers' loading of
    the module excluded), ``workers`` how many."""

    total: int
    computed: list[int] = field(default_factory=list)
    rows: int = 0
    skipped: int = 0
    failed: dict[int, str] = field(default_factory=dict)
    seconds: float = 0.0
    workers: int = 0


@contextlib.contextmanager
def connect(scheduler: str | None = None, workers: int = 2) -> Iterator[Client]:
    """A ``distributed.Client``: to the scheduler at ``scheduler``, else to a new LocalCluster of
    ``workers`` single-threaded processes (closed on exit)."""
    from distributed import Client, LocalCluster

    if scheduler is not None:
        with Client(scheduler, timeout="30s") as client:
            yield client
        return
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise SweepError(f"workers: expected a positive integer, got {workers!r}")
    # the scheduler's HTTP server starts even without a dashboard: on a free port (":0"), never clashing
    # with another cluster on 8787
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        yield client


def _warm_up(sweep: Sweep) -> None:
    """Build and compile what the workers would otherwise build at once on first use (the system's
    generated module, the iLQR loop library): safe to race, but two workers doing it at once cost two
    cores the sweep wants."""
    from gagen.sweep.problems import build_module

    build_module(sweep.system)
    if sweep.kind == "reach":
        from gagen.control.ilqr import loop_library

        loop_library()


def run(sweep: Sweep, out: str | Path, *, client: Client | None = None, scheduler: str | None = None,
        workers: int = 2, progress: bool = True,
        on_written: Callable[[int], None] | None = None) -> Outcome:
    """Compute every chunk of ``sweep`` not yet in ``out`` and write each as it arrives; ``client``: an
    open ``distributed.Client`` to use (else one from ``connect(scheduler, workers)``). ``on_written(i)``
    is called after chunk i's file is in place. Chunks whose task raised are listed in ``failed`` (the
    others are still written); a re-run retries them."""
    store = ChunkStore(out)
    store.claim(sweep.description())
    store.clear_partials()
    outcome = Outcome(total=sweep.chunks)
    done = store.finished()
    todo = [i for i in range(sweep.chunks) if i not in done]
    outcome.skipped = sweep.chunks - len(todo)
    if not todo:
        return outcome
    _warm_up(sweep)
    with contextlib.ExitStack() as stack:
        if client is None:
            client = stack.enter_context(connect(scheduler, workers))
        outcome.workers = len(client.scheduler_info(n_workers=-1)["workers"])
        _compute(client, sweep, todo, store, outcome, progress, on_written)
    return outcome


def _compute(client: Client, sweep: Sweep, todo: list[int], store: ChunkStore, outcome: Outcome,
             progress: bool, on_written: Callable[[int], None] | None) -> None:
    from distributed import as_completed
    from tqdm import tqdm

    client.run(prepare, sweep)  # every worker loads the module first: ``seconds`` times the chunks alone
    started = time.perf_counter()
    run_id = uuid.uuid4().hex[:8]  # task keys unique to this run: a re-run never meets a stale result
    futures = {client.submit(compute_chunk, sweep, i, key=f"sweep-{sweep.kind}-{run_id}-{i}", pure=False): i
               for i in todo}
    bar = tqdm(total=sweep.chunks, initial=outcome.skipped, unit="chunk", desc=f"{sweep.kind} sweep",
               disable=not progress, smoothing=0.1)
    try:
        # with_results: the rows are gathered in the background as tasks finish, not one round trip each;
        # raise_errors=False: a chunk whose task raised comes back as its exception, the others go on
        for future, result in as_completed(list(futures), with_results=True, raise_errors=False):
            index, status = futures.pop(future), future.status
            future.release()  # the rows live on a worker until released: a long sweep would pile up
            if status == "error":  # the result is then (type, exception, traceback)
                outcome.failed[index] = f"{type(result[1]).__name__}: {result[1]}"
                continue
            if status != "finished":  # cancelled: the scheduler went away or someone cancelled it
                outcome.failed[index] = f"task {status}"
                continue
            _, table = result
            store.write(index, table)
            outcome.computed.append(index)
            outcome.rows += table.num_rows
            bar.update(1)
            if on_written is not None:
                on_written(index)
    finally:
        bar.close()
        outcome.seconds = time.perf_counter() - started
        if futures:  # an interrupted run leaves nothing queued on a shared cluster
            client.cancel(list(futures))


def run_serial(sweep: Sweep, out: str | Path) -> Outcome:
    """The same sweep in this process, one chunk after another (no Dask): the reference the distributed
    runs are checked against, and the baseline of the benchmark."""
    store = ChunkStore(out)
    store.claim(sweep.description())
    store.clear_partials()
    outcome = Outcome(total=sweep.chunks, workers=0)
    done = store.finished()
    outcome.skipped = len(done & set(range(sweep.chunks)))
    started = time.perf_counter()
    for i in range(sweep.chunks):
        if i not in done:
            _, table = compute_chunk(sweep, i)
            store.write(i, table)
            outcome.computed.append(i)
            outcome.rows += table.num_rows
    outcome.seconds = time.perf_counter() - started
    return outcome

"""The calibrator's worker processes: their pool, their start and their end. No rclpy here.

A Ctrl-C reaches the whole process group, the workers included, and stopping them is the
node's job. So a worker ignores SIGINT from its first instruction on: it is spawned with SIGINT
ignored (the disposition survives the exec of a spawned process; the signal mask does not).
Only the main thread may change a disposition; the calibrator's executor spins there, and its
SIGINT handler is a Python one (rclpy installs none: ``SignalHandlerOptions.NO``), which
``signal.signal`` puts back as it was. Where the handler is not Python's (rclpy's own, in
another program), a worker ignores SIGINT from its initializer on, a moment after it starts.

Spawning a worker also starts multiprocessing's resource tracker, a child of the node. It ends
by itself once the node has exited (it reads its pipe until the last writer closes it), as in
any Python program that spawns processes; Python has no public call that would end it sooner,
and the node calls no private one. Reaping it is then the job of the system's init (a PID 1
that does not reap, as in some sandboxes, leaves it a zombie: ended, not running).
"""

from __future__ import annotations

import concurrent.futures as cf
import importlib
import multiprocessing
import os
import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from multiprocessing.queues import SimpleQueue
from typing import TypeVar

_R = TypeVar('_R')

#: What a calibration in the worker imports (the application, the evaluation, the snapshot's
#: class and the core with scipy.optimize): imported when the worker starts, not on the first call.
MODULES = (
    'handeye_ros.ros.jobs',
    'handeye_ros.evaluation.outputs',
    'handeye_ros.stream.recorder',
    'handeye_ros.core.pipeline',
)


#: Worker processes: one for calibrations, one for the status (either takes either job). The
#: first starts with the node; the second when a job comes while the first is busy (the
#: status while a calibration runs): a node that never has two jobs at once never pays for its
#: start (0.6 s of CPU, 80 MB).
WORKERS = 2
#: BLAS threads of a worker, unless the user's environment says otherwise. Its jobs are small
#: matrices: a calibration (5 min of 200 + 30 Hz, 2 min of 1 kHz + 200 Hz) takes the same wall
#: time with one thread as with two, and 27-37 % less CPU, which ingest and the status's
#: budget (status.MAX_DUTY) pay for. Read by OpenBLAS when the spawned worker imports numpy.
BLAS_THREADS = {'OPENBLAS_NUM_THREADS': '1', 'OMP_NUM_THREADS': '1', 'MKL_NUM_THREADS': '1'}


class Pool:
    """The worker processes: a ProcessPoolExecutor, and the process ids its workers said as
    they started (the executor keeps its processes to itself; stopping a running call needs
    them)."""

    def __init__(self, executor: cf.ProcessPoolExecutor, said: SimpleQueue[int]):
        self._executor, self._said = executor, said
        self._pids: list[int] = []

    def submit(self, fn: Callable[..., _R], *args: object) -> cf.Future[_R]:
        """A job (RuntimeError once the pool is stopped). When every worker started is busy,
        the executor spawns another in this call: until all WORKERS have, SIGINT is ignored
        during the call."""
        if len(self._heard()) >= WORKERS:
            return self._executor.submit(fn, *args)
        with _sigint_ignored():
            return self._executor.submit(fn, *args)

    def _heard(self) -> list[int]:
        """The process ids the workers have said so far."""
        while not self._said.empty():
            self._pids.append(self._said.get())
        return self._pids

    def stop(self) -> None:
        """Stop the workers and wait for them; a running call is abandoned (SIGTERM: the
        executor has no public way to stop one), and shutdown then joins them."""
        for pid in self._heard():
            try:
                os.kill(pid, signal.SIGTERM)
            except ProcessLookupError:  # ended already
                pass
        self._executor.shutdown(wait=True, cancel_futures=True)


def new_pool() -> Pool:
    """A pool of up to WORKERS spawned workers (spawn, not fork: the node's DDS threads must not
    be forked), the first started now and with the core imported, so that a call pays no
    start-up. Returns once it has: the executor counts a worker idle only once it has finished
    a job, and a job that found none idle would start the second."""
    for name, value in BLAS_THREADS.items():
        # in the node's own environment (its numpy has loaded its BLAS already): a spawned
        # worker inherits it, and a pool renewed later finds it set, with no change under the
        # DDS threads
        os.environ.setdefault(name, value)
    context = multiprocessing.get_context('spawn')
    said = context.SimpleQueue()
    executor = cf.ProcessPoolExecutor(
        max_workers=WORKERS, initializer=start, initargs=(said,), mp_context=context
    )
    pool = Pool(executor, said)
    pool.submit(int).result()  # finds no idle worker (none has started yet): spawns one
    return pool


@contextmanager
def _sigint_ignored() -> Iterator[None]:
    """SIGINT ignored while a worker may be spawned, so that it starts ignoring it (see the
    module docstring); blocked too in this thread, where a Ctrl-C in these microseconds stays
    pending and reaches the handler put back (one that another thread takes then, a DDS thread
    once rclpy runs, is lost: press again). Nothing outside the main thread, or where the
    handler is not Python's."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.getsignal(signal.SIGINT)
    if previous is None:  # installed outside Python: signal.signal could not put it back
        yield
        return
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def stop(pool: Pool) -> None:
    """Stop the worker and wait for it; a running call is abandoned (:meth:`Pool.stop`)."""
    pool.stop()


def start(said: SimpleQueue[int]) -> None:
    """Process pool initializer: ignore SIGINT, say this worker's process id, import the
    core."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    said.put(os.getpid())
    for module in MODULES:
        importlib.import_module(module)

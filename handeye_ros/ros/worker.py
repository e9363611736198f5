"""The calibrator's worker process: its pool, its start and its end. No rclpy here.

A Ctrl-C reaches the whole process group, the worker included, and stopping the worker is the
node's job. So the worker ignores SIGINT, from its first instruction on: the node starts it
with SIGINT ignored (the disposition survives the exec of a spawned process; the signal mask
does not), before rclpy installs its own handlers, which ``signal.signal`` would replace.

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
from collections.abc import Callable
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


#: Worker processes: one for calibrations, one for the status (either takes either job).
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
        """A job (RuntimeError once the pool is stopped)."""
        return self._executor.submit(fn, *args)

    def stop(self) -> None:
        """Stop the workers and wait for them; a running call is abandoned (SIGTERM: the
        executor has no public way to stop one), and shutdown then joins them."""
        while not self._said.empty():
            self._pids.append(self._said.get())
        for pid in self._pids:
            try:
                os.kill(pid, signal.SIGTERM)
            except ProcessLookupError:  # ended already
                pass
        self._executor.shutdown(wait=True, cancel_futures=True)


def new_pool(ignore_sigint: bool = True) -> Pool:
    """A pool of WORKERS spawned workers (spawn, not fork: the node's DDS threads must not be
    forked), started now and with the core imported, so that a call pays no start-up: a
    calibration and the readiness status can run at once.

    ``ignore_sigint``: start it with SIGINT ignored (see the module docstring); only from the
    main thread and before rclpy.init. A pool renewed later (after a worker crashed) cannot,
    and ignores SIGINT from its initializer on, a second after it starts."""
    for name, value in BLAS_THREADS.items():
        # in the node's own environment (its numpy has loaded its BLAS already): a spawned
        # worker inherits it, and a pool renewed later finds it set, with no change under the
        # DDS threads
        os.environ.setdefault(name, value)
    if ignore_sigint:
        # blocked as well as ignored: Linux never discards a blocked signal, so a Ctrl-C in
        # these milliseconds stays pending and reaches the handler restored below
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    context = multiprocessing.get_context('spawn')
    said = context.SimpleQueue()
    try:
        executor = cf.ProcessPoolExecutor(
            max_workers=WORKERS, initializer=start, initargs=(said,), mp_context=context
        )
        # each call finds no idle worker (none has started yet) and spawns one, now
        for _ in range(WORKERS):
            executor.submit(int)
    finally:
        if ignore_sigint:
            signal.signal(signal.SIGINT, previous)
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    return Pool(executor, said)


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

"""Tunings that share their batches: several tasks (the rows of one benchmark scenario) each run in a thread of
their own, and the runs they ask for go into one mixed batch a round.

A round of a tuning costs the batch engine's Python overhead per step, whatever the batch's size, and a
scenario's rows differ only in some of their classes (estimator, controller, servo): run one at a time, each row
pays that overhead for every one of its rounds. Here each task runs in its own thread, and every call it makes
to :func:`contouring_ros.studies.sweep.simulate_loops` (nominal runs, robustness runs, a learning controller's
passes, the draws) waits until every task still running has asked for its next runs; then all of them run
together (``simulate_loops`` with ``mixed``: one mixed batch per path, each part of the loop stacked per class),
and each task gets its own results back. A step then costs one call per class of each part, not one per row.

Only one thread runs at a time (each holds the turn until it waits for a round or ends; the rounds run in
the caller's thread), so the tasks' own work (their searches, building and scoring their runs) never
interleaves: a task computes what it computes alone. A round holds the next request of every task still
running, in task order, so the rounds and what they hold are the same run after run. Each member's numbers
are those it has in a batch of its own structure (core/batch.py), whatever shares its round; but a run that
would run alone (a batch smaller than its classes' minimum) can run batched here, which changes its last
digits (as any other change of batch size does).

The CPU time of a round is shared among the tasks whose runs it held, by their member-steps
(:attr:`SharedBatches.cpu`), so that each task's CPU time is its own work and its share of the rounds.
"""
from __future__ import annotations

import threading
import time

import numpy as np

__all__ = ["SharedBatches", "current_batches"]

_local = threading.local()


def current_batches():
    """The :class:`SharedBatches` this thread's runs go to, or None (outside a shared task, or while it runs a
    round)."""
    return getattr(_local, "batches", None)


class SharedBatches:
    """Tasks run in threads of their own whose runs share one batch a round (see the module docstring):
    :meth:`run` them, then read each one's CPU seconds in :attr:`cpu`. ``finished(i, result, cpu)``, where
    given, is called as task i ends, with its result and CPU seconds (the rounds after it owe it nothing).

    The rounds run in the thread that called :meth:`run`: a batch's large arrays are then always made and
    freed by one thread (the C library's allocator keeps memory per thread, and rounds run by whichever task
    came last grew every task's share to the largest round)."""

    def __init__(self, finished=None):
        self.finished = finished    # finished(i, result, cpu): called as task i ends (in its thread, in turn)
        self._turn = threading.Condition()
        self._live = 0
        self._waiting = {}          # task -> the loops it asks for
        self._answers = {}          # task -> (results, alone, failures) or the exception its round raised
        self._run_round = None      # run_round(loops) of the latest request (sweep.simulate_loops, mixed)
        self._shares = {}           # task -> CPU seconds of rounds given to it (its member-steps' share)
        self.cpu = []               # each task's CPU seconds: its own work and its share of the rounds
        self.rounds = 0             # rounds run
        self.members = 0            # runs in them

    def run(self, tasks: list) -> list:
        """Each of ``tasks`` (callables without arguments) in its own thread, their runs shared; returns their
        results in order. Where a task raised, the first such exception is raised once all have ended."""
        results, errors = [None] * len(tasks), [None] * len(tasks)
        self.cpu = [0.0] * len(tasks)
        self._live = len(tasks)
        self._shares = {i: 0.0 for i in range(len(tasks))}

        def body(i, task):
            _local.batches, _local.task = self, i
            with self._turn:
                started = time.thread_time()
                try:
                    results[i] = task()
                except BaseException as error:      # noqa: BLE001 - handed to the caller after every task ends
                    errors[i] = error
                finally:
                    _local.batches = None
                    self.cpu[i] = time.thread_time() - started + self._shares[i]
                    if self.finished is not None and errors[i] is None:
                        try:
                            self.finished(i, results[i], self.cpu[i])
                        except BaseException as error:      # noqa: BLE001 - as the task's own
                            errors[i] = error
                    self._live -= 1
                    self._turn.notify_all()

        threads = [threading.Thread(target=body, args=(i, task), name=f"shared-batches-{i}", daemon=True)
                   for i, task in enumerate(tasks)]
        with self._turn:
            for thread in threads:
                thread.start()
            while True:
                self._turn.wait_for(lambda: not self._live or len(self._waiting) == self._live)
                if not self._live:
                    break
                self._round()
        for thread in threads:
            thread.join()
        for error in errors:
            if error is not None:
                raise error
        return results

    def simulate(self, loops: list, run_round) -> tuple:
        """What :func:`contouring_ros.studies.sweep.simulate_loops` returns for ``loops``, run in this round's
        mixed batch with every other task's loops (called from a task's thread, holding the turn).
        ``run_round(loops)`` runs a round's loops and returns (results, alone, failures), one entry a loop;
        the round runs with the last request's."""
        task = _local.task
        self._waiting[task] = list(loops)
        self._run_round = run_round
        self._turn.notify_all()
        self._turn.wait_for(lambda: task in self._answers)
        answer = self._answers.pop(task)
        if isinstance(answer, BaseException):
            raise answer
        return answer

    def _round(self) -> None:
        """Run the round every task still running waits for (in the caller of :meth:`run`, the turn held)."""
        tasks = sorted(self._waiting)
        asked = [self._waiting.pop(task) for task in tasks]
        loops = [loop for mine in asked for loop in mine]
        started = time.thread_time()
        try:
            with np.errstate(all="ignore"):         # a diverging run overflows; each task is told how it ended
                results, alone, failures = self._run_round(loops)
        except BaseException as error:              # noqa: BLE001 - every task of the round gets it
            for task in tasks:
                self._answers[task] = error
        else:
            at = 0
            for task, mine in zip(tasks, asked):
                self._answers[task] = (results[at:at + len(mine)], alone[at:at + len(mine)],
                                       failures[at:at + len(mine)])
                at += len(mine)
        spent = time.thread_time() - started
        self.rounds += 1
        self.members += len(loops)
        steps = [sum(loop.n_steps for loop in mine) for mine in asked]
        total = sum(steps) or 1
        for task, share in zip(tasks, steps):
            self._shares[task] += spent * share / total
        self._turn.notify_all()

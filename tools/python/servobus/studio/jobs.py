"""The worker's queue of jobs, and the refusals the studio answers with.

A job is one action's bus work (a function of the Bus) with what the log says about
it, whether it moves a servo, and its priority: STOP's jobs (0) go before everything
queued. STOP cancels every queued motion; losing the bus cancels every queued job:
their requests are answered at once with the reason, and nothing of them is sent."""

import concurrent.futures
import heapq
import itertools
import threading
import time


class Refused(Exception):
    """An action refused with a sentence and an HTTP status (4xx): 400 what was given
    is wrong, 409 the studio's state does not allow it now, 422 the bus or a servo
    said no after something was sent. sent: whether anything went on the wire."""

    def __init__(self, text, status=409, sent=False, **extra):
        super().__init__(text)
        self.status = status
        self.sent = sent
        self.extra = extra


class BusGone(Refused):
    """The bus is not there (unplugged, servo-sim stopped): nothing can be sent."""

    def __init__(self, text):
        super().__init__(text, 409)


class Job:
    """One action's work for the worker thread."""

    __slots__ = ("fn", "what", "motion", "prio", "future")

    def __init__(self, fn, what=None, motion=False, prio=1):
        self.fn = fn          # fn(bus) -> result, run in the worker thread
        self.what = what      # the log's words for it (None: not logged, e.g. a READ)
        self.motion = motion  # it moves a servo: STOP cancels it while queued
        self.prio = prio      # 0: STOP's own jobs, before everything else
        self.future = concurrent.futures.Future()


class JobQueue:
    """Jobs by priority, then in the order they came (thread-safe)."""

    def __init__(self):
        self._cv = threading.Condition()
        self._heap = []
        self._seq = itertools.count()

    def put(self, job):
        with self._cv:
            heapq.heappush(self._heap, (job.prio, next(self._seq), job))
            self._cv.notify()
        return job.future

    def get(self, timeout):
        """The next job, or None after timeout seconds without one."""
        deadline = time.monotonic() + timeout
        with self._cv:
            while not self._heap:
                left = deadline - time.monotonic()
                if left <= 0 or not self._cv.wait(left):
                    if not self._heap:
                        return None
            return heapq.heappop(self._heap)[2]

    def cancel(self, which, error):
        """Take every queued job for which which(job) is true out of the queue, its
        request answered with error. Returns how many."""
        with self._cv:
            keep = [item for item in self._heap if not which(item[2])]
            gone = [item[2] for item in self._heap if which(item[2])]
            self._heap = keep
            heapq.heapify(self._heap)
        for job in gone:
            if job.future.set_running_or_notify_cancel():
                job.future.set_exception(error)
        return len(gone)

    def __len__(self):
        with self._cv:
            return len(self._heap)

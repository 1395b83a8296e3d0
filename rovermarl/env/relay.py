"""Helper threads that share ``World.evaluate_many``'s passes with the calling thread, and wait for the next
population in compiled code (:mod:`~rovermarl.env.kernel.mailbox`, the world's ``compiled.serve``).

A helper woken through Python for every call started about 100 us late and cost the caller 40-50 us, a tenth of a
two-core call of 64 float32 teams. Here the caller posts the population's arrays to a mailbox and takes passes at
once; a helper that is still waiting (for :data:`IDLE_SECONDS` after its last job) joins within a microsecond, one
asleep is woken through a semaphore. Each process has one :class:`Relay` (a forked child makes its own); a second
thread calling at the same time runs its population alone.
"""

from __future__ import annotations

import os
import threading
import time

import numpy as np

from rovermarl.env.kernel import mailbox

IDLE_SECONDS = 0.002    # how long a helper waits in compiled code after its last job before it sleeps
_RELAYS: dict[int, Relay] = {}
_LOCK = threading.Lock()


class Relay:
    """``helpers`` daemon threads and their mailbox. :meth:`run` scores a population on them and the calling thread."""

    def __init__(self, helpers: int):
        self.box = np.zeros(mailbox.BOX, dtype=np.int64)
        self.counters = np.zeros(1, dtype=np.int64)
        self.busy = threading.Lock()                      # one caller at a time
        self.wake = threading.Semaphore(0)
        self.binding: tuple | None = None                 # (serve, xy, heading, fields, epoch) the helpers run
        self.error: BaseException | None = None
        self.idle = _idle_spins()
        self.helpers = [threading.Thread(target=self._helper, name="rovermarl-relay", daemon=True)
                        for _ in range(helpers)]
        for t in self.helpers:
            t.start()

    def run(self, compiled, p, args: tuple, threads: int) -> bool:
        """``compiled.evaluate_many`` of args (teams, returns, scores, sane, final, per_pass) on the initial
        conditions ``p`` (a ``Prepared``), on this thread and up to ``threads - 1`` helpers; False (nothing run) if
        another thread is using the relay."""
        if not self.busy.acquire(blocking=False):
            return False
        try:
            self._bind(compiled.serve, p)
            teams, returns, scores, sane, final, per_pass = args
            seats = min(threads - 1, len(self.helpers))
            gen = mailbox.post(self.box, teams, returns, scores, sane, final, per_pass, self.counters, seats)
            for _ in range(seats - int(self.box[mailbox.AWAKE])):
                self.wake.release()
            try:
                compiled.evaluate_many(teams, p.xy, p.heading, p.fields, returns, scores, sane, final, per_pass,
                                       self.counters)
            finally:
                done = mailbox.close(self.box, gen)       # waits for the helpers' passes; the arrays stay alive
            if not done:
                _forget(self)
                raise self.error
            return True
        finally:
            self.busy.release()

    def _bind(self, serve, p) -> None:
        """Point the helpers at ``serve`` on ``p``'s arrays; the helpers of another binding return to Python."""
        if self.binding is not None and self.binding[0] is serve and self.binding[1] is p.xy \
                and self.binding[2] is p.heading and self.binding[3] is p.fields:
            return
        # Compile (or load) serve here, not in a helper: numba's compiler sets the process's warning filters, which
        # would break a `warnings.catch_warnings` running meanwhile in this thread. Epoch -1 returns at once.
        serve(p.xy, p.heading, p.fields, self.box, self.counters, -1, 0)
        epoch = int(self.box[mailbox.EPOCH]) + 1
        self.binding = (serve, p.xy, p.heading, p.fields, epoch)
        self.box[mailbox.EPOCH] = epoch
        while self.box[mailbox.AWAKE]:                    # they leave within a read of the box
            time.sleep(0)

    def _helper(self) -> None:
        while True:
            self.wake.acquire()
            binding = self.binding
            if binding is None:                           # this relay was forgotten
                return
            serve, xy, heading, fields, epoch = binding
            try:
                serve(xy, heading, fields, self.box, self.counters, epoch, self.idle)
            except BaseException as e:                    # noqa: BLE001 - the caller raises it (Relay.run)
                self.error = e
                mailbox.fail(self.box)
                return

    def close(self) -> None:
        """Send the helpers home (their next wake ends them)."""
        self.binding = None
        self.box[mailbox.EPOCH] += 1
        for _ in self.helpers:
            self.wake.release()


def relay(helpers: int) -> Relay:
    """This process's relay, with at least ``helpers`` helper threads."""
    with _LOCK:
        r = _RELAYS.get(os.getpid())
        if r is None or len(r.helpers) < helpers:
            if r is not None:
                r.close()
            _RELAYS[os.getpid()] = r = Relay(helpers)
        return r


def _forget(r: Relay) -> None:
    with _LOCK:
        if _RELAYS.get(os.getpid()) is r:
            del _RELAYS[os.getpid()]
    r.close()


def _idle_spins() -> int:
    """Spin-wait hints in :data:`IDLE_SECONDS` on this CPU (timed once a relay: about 1 ms)."""
    mailbox.spin(1)
    n = 20_000
    t = time.perf_counter()
    mailbox.spin(n)
    return max(1, int(n * IDLE_SECONDS / max(time.perf_counter() - t, 1e-9)))

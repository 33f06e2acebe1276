"""Ctrl-C sent to this process while (and only while) a piece of work runs: a signal that came
after the work ended would interrupt the test session itself, and a test that could not stop
the whole run is the only kind a flaky machine cannot turn into a red CI without a reason."""

import _thread
import os
import signal
import threading
import time


def send_sigint():
    """A real SIGINT, as a terminal's Ctrl-C sends it."""
    os.kill(os.getpid(), signal.SIGINT)


class InterruptDuring:
    """Context manager: interrupts the main thread `delay_s` after it is entered, unless it has
    been left by then. `sent` holds the `time.perf_counter()` of the interrupt when one was sent.

    `send` is how: `_thread.interrupt_main` (default; raises KeyboardInterrupt on any platform)
    or :func:`send_sigint`."""

    def __init__(self, delay_s, send=_thread.interrupt_main):
        self.sent = []
        self._send = send
        self._lock = threading.Lock()
        self._active = True
        self._timer = threading.Timer(delay_s, self._fire)

    def _fire(self):
        with self._lock:
            if self._active:
                self.sent.append(time.perf_counter())
                self._send()

    def __enter__(self):
        self._timer.start()
        return self

    def __exit__(self, *exception):
        with self._lock:
            self._active = False
        self._timer.cancel()
        return False

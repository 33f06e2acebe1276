"""Ctrl-C during a long conversion is answered within 100 ms: the conversion runs with the GIL
released and looks for signals as it goes, and raises KeyboardInterrupt."""

import os
import signal
import threading
import time

import numpy as np
import pytest

import taxel
from interrupting import InterruptDuring, send_sigint

# Enough rows that the conversion takes far longer than the wait before the signal, in a debug
# build (a few µs per row) and in a release build (about 0.1 µs per row) alike: 20 million rows
# of one pad (640 MB of float64 input) in release terms, fewer in a debug build.
SIGNAL_AFTER_S = 0.4


def rows_for_at_least(seconds):
    """Rows whose conversion takes at least `seconds`, from a timed sample."""
    sample = np.full((20_000, 4), 5.0)
    sample[1:] += np.random.default_rng(3).uniform(0.0, 0.5, (len(sample) - 1, 4))
    started = time.perf_counter()
    taxel.convert(sample, np.full(len(sample), 25.0))
    per_row_s = (time.perf_counter() - started) / len(sample)
    return int(min(20_000_000, max(1_000_000, seconds / per_row_s)))


@pytest.mark.skipif(not hasattr(signal, "SIGINT") or os.name != "posix", reason="POSIX signals")
def test_ctrl_c_interrupts_a_large_convert_within_100_ms():
    rows = rows_for_at_least(6 * SIGNAL_AFTER_S)
    capacitance = np.full((rows, 4), 5.0)
    temperature = np.full(rows, 25.0)
    started = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        with InterruptDuring(SIGNAL_AFTER_S, send_sigint) as sigint:
            taxel.convert(capacitance, temperature)
    raised = time.perf_counter()
    assert sigint.sent, "the conversion ended before the signal: give it more rows"
    delay_ms = (raised - sigint.sent[0]) * 1e3
    assert delay_ms < 100, f"KeyboardInterrupt {delay_ms:.1f} ms after SIGINT ({rows:,} rows)"
    assert raised - started < 3 * SIGNAL_AFTER_S + 1
    # The package is still usable afterwards.
    pressure, _ = taxel.convert(capacitance[:10], temperature[:10])
    assert pressure.shape == (10, 4)


@pytest.mark.skipif(os.name != "posix", reason="POSIX signals")
def test_other_threads_run_during_a_convert():
    # The GIL is released: a Python thread keeps counting while the conversion runs.
    rows = rows_for_at_least(0.5)
    capacitance = np.full((rows, 4), 5.0)
    counted = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            counted.append(1)
            time.sleep(0.001)

    thread = threading.Thread(target=count)
    thread.start()
    try:
        before = len(counted)
        taxel.convert(capacitance, np.full(rows, 25.0))
        during = len(counted) - before
    finally:
        stop.set()
        thread.join()
    assert during > 50

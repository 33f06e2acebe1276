"""The Python package's performance figures, printed as a markdown table.

1. ``taxel.convert`` of 1 000 000 rows of four taxels with the default calibration and tier,
   against a vectorised numpy implementation of the same thing written for this benchmark: the
   tare on the first row, dC/C0, and the inverse of the default tier's monotone (Fritsch-Carlson)
   cubic by vectorised Newton steps. Both run on one core (numpy's element-wise operations are
   single-threaded); the table gives the best of several runs, and how far the two results are
   apart (they must agree, or the comparison would mean nothing).
2. The simulated device's sample sets per second through the Python iterator
   (``for sample in taxel.Simulator(speed=None)``), and how many times real time that is (device
   seconds per wall-clock second).

Regenerate: ``pip install ./python && python python/benchmarks/convert_bench.py``.
Goals: convert at least 5x faster than numpy and under 100 ms; the iterator at least 100x real
time.
"""

import argparse
import json
import os
import platform
import sys
import time

import numpy as np

import taxel

ROWS = 1_000_000
TAXELS = 4


def default_curve():
    """The default calibration's first taxel: curve points (pressure, dC/C0) and parasitic pF
    (every taxel of the default is the same)."""
    spec = json.loads(taxel.Calibration.default().to_json())["calibration"]
    first = spec["taxels"][0]
    for other in spec["taxels"][1:]:
        assert other == first, "the benchmark assumes one curve for every taxel"
    pressure = np.array([point["pressure_kpa"] for point in first["points"]], dtype=np.float64)
    change = np.array([point["relative_change"] for point in first["points"]], dtype=np.float64)
    return pressure, change, float(first["parasitic_pf"])


def fritsch_carlson(xs, ys):
    """Per interval: start x, start y and the cubic's coefficients in the local coordinate, as
    the model builds them (three-point mean tangents, limited to the circle of radius 3)."""
    secants = np.diff(ys) / np.diff(xs)
    tangents = np.empty_like(xs)
    tangents[0], tangents[-1] = secants[0], secants[-1]
    inner = 0.5 * (secants[:-1] + secants[1:])
    inner[secants[:-1] * secants[1:] <= 0] = 0.0
    tangents[1:-1] = inner
    for k, secant in enumerate(secants):
        alpha, beta = tangents[k] / secant, tangents[k + 1] / secant
        radius_squared = alpha * alpha + beta * beta
        if radius_squared > 9.0:
            tau = 3.0 / np.sqrt(radius_squared)
            tangents[k], tangents[k + 1] = tau * alpha * secant, tau * beta * secant
    width = np.diff(xs)
    c1 = tangents[:-1]
    c2 = (3.0 * secants - 2.0 * tangents[:-1] - tangents[1:]) / width
    c3 = (tangents[:-1] + tangents[1:] - 2.0 * secants) / (width * width)
    return xs[:-1], ys[:-1], width, c1, c2, c3


def numpy_convert(capacitance_pf, curve):
    """The default tier in numpy: tare on the first row, dC/C0, monotone-cubic inverse; NaN
    above the curve's top and below the baseline's dead band is taken as 0 kPa."""
    (x0, y0, width, c1, c2, c3), top_change, parasitic_pf = curve
    sensor_pf = capacitance_pf - parasitic_pf
    change = sensor_pf / sensor_pf[0] - 1.0
    inside = (change > 0.0) & (change <= top_change)
    target = np.where(inside, change, 0.0)
    segment = np.clip(np.searchsorted(y0, target, side="right") - 1, 0, len(y0) - 1)
    a0, a1, a2, a3, w = y0[segment] - target, c1[segment], c2[segment], c3[segment], width[segment]
    s = np.where(a1 > 0, -a0 / np.where(a1 > 0, a1, 1.0), 0.0)
    for _ in range(6):
        value = a0 + s * (a1 + s * (a2 + s * a3))
        slope = a1 + s * (2.0 * a2 + s * 3.0 * a3)
        s = np.clip(s - value / np.where(slope > 0, slope, 1.0), 0.0, w)
    pressure = x0[segment] + s
    pressure = np.where(inside, pressure, np.where(change > top_change, np.nan, 0.0))
    return pressure


def best_of(runs, functions):
    """Per function, the shortest wall-clock and CPU times (this thread's: every implementation
    runs on the calling thread) of `runs` calls, and its last result. The calls take turns, so
    that a machine whose speed drifts (a shared virtual machine) slows them all alike."""
    best = {name: [float("inf"), float("inf")] for name in functions}
    results = {}
    for _ in range(runs):
        for name, function in functions.items():
            wall_started, cpu_started = time.perf_counter(), time.thread_time()
            results[name] = function()
            cpu_s = time.thread_time() - cpu_started
            wall_s = time.perf_counter() - wall_started
            best[name] = [min(best[name][0], wall_s), min(best[name][1], cpu_s)]
    return {name: (tuple(best[name]), results[name]) for name in functions}


def convert_figures(runs):
    pressure_points, change_points, parasitic_pf = default_curve()
    curve = (fritsch_carlson(pressure_points, change_points), change_points[-1], parasitic_pf)
    rng = np.random.default_rng(1)
    applied_kpa = rng.uniform(0.0, 0.9 * pressure_points[-1], (ROWS, TAXELS))
    applied_kpa[0] = 0.0
    # Capacitances of those pressures through the default curve (piecewise-linear is enough
    # to make realistic data; both implementations then invert the same numbers).
    change = np.interp(applied_kpa, pressure_points, change_points)
    capacitance_pf = (parasitic_pf + 4.5 * (1.0 + change)).astype(np.float32).astype(np.float64)
    temperature_c = np.full(ROWS, 25.0)
    taxel.convert(capacitance_pf[:1000], temperature_c[:1000])
    timed = best_of(runs, {
        "default": lambda: taxel.convert(capacitance_pf, temperature_c),
        "numpy": lambda: numpy_convert(capacitance_pf, curve),
        "table": lambda: taxel.convert(capacitance_pf, temperature_c, tier="table"),
        "polynomial": lambda: taxel.convert(capacitance_pf, temperature_c, tier="polynomial"),
    })
    taxel_s, (taxel_kpa, _) = timed["default"]
    numpy_s, numpy_kpa = timed["numpy"]
    # Row 0 is the tare row (no pressure from the model; 0 from numpy).
    both = np.isfinite(taxel_kpa[1:]) & np.isfinite(numpy_kpa[1:])
    difference_kpa = float(np.max(np.abs(taxel_kpa[1:][both] - numpy_kpa[1:][both])))
    faster_tiers = {tier: timed[tier][0] for tier in ("table", "polynomial")}
    return taxel_s, numpy_s, difference_kpa, float(np.mean(both)), faster_tiers


def iterator_figures(seconds):
    with taxel.Simulator(speed=None) as sim:
        sim.read()
        count, gaps = 0, 0
        first = last = None
        started = time.perf_counter()
        for sample in sim:
            if first is None:
                first = sample.device_time_us
            last = sample.device_time_us
            gaps += sample.sets_missing_before
            count += 1
            if count % 256 == 0 and time.perf_counter() - started >= seconds:
                break
        elapsed_s = time.perf_counter() - started
        stats = sim.stats
    device_s = (last - first) / 1e6
    return count / elapsed_s, device_s / elapsed_s, gaps, stats


def met(condition):
    """A goal's verdict as the table prints it."""
    return "met" if condition else "**not met**"


def main():
    parser = argparse.ArgumentParser(description="The Python package's performance table")
    parser.add_argument("--runs", type=int, default=15, help="timed runs of each conversion")
    parser.add_argument("--seconds", type=float, default=3.0, help="iterator measurement, s")
    arguments = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        # One core for everything, as the goal says.
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    taxel_s, numpy_s, difference_kpa, compared, faster_tiers = convert_figures(arguments.runs)
    sets_per_s, real_time_factor, gaps, stats = iterator_figures(arguments.seconds)
    print("# The Python package's performance\n")
    print("Generated by `pip install ./python && python python/benchmarks/convert_bench.py > "
          "python/PERFORMANCE.md` (the benchmark's docstring says what it measures); do not edit "
          "by hand.\n")
    print(f"Python {platform.python_version()}, numpy {np.__version__}, "
          f"{platform.machine()}, one core; best of {arguments.runs} runs; "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores.\n")
    print("CPU time is the calling thread's (both run there); wall-clock time also counts "
          "waiting for a core on a busy machine.\n")
    print("| measurement | value | goal |")
    print("|---|---|---|")
    print(f"| `taxel.convert`, {ROWS:,} rows x {TAXELS} taxels (default calibration and tier) "
          f"| {taxel_s[1] * 1e3:.1f} ms CPU ({taxel_s[0] * 1e3:.1f} ms wall) "
          f"| under 100 ms: {met(taxel_s[1] < 0.1)} |")
    print(f"| numpy, the same default-tier inverse vectorised "
          f"| {numpy_s[1] * 1e3:.1f} ms CPU ({numpy_s[0] * 1e3:.1f} ms wall) | |")
    print(f"| numpy time / `taxel.convert` time (CPU) | {numpy_s[1] / taxel_s[1]:.1f}x "
          f"| at least 5x: {met(numpy_s[1] / taxel_s[1] >= 5.0)} |")
    print(f"| largest difference between the two (over {compared:.1%} of the values) "
          f"| {difference_kpa:.2g} kPa | |")
    for tier, (wall_s, cpu_s) in faster_tiers.items():
        print(f"| `taxel.convert` with `tier=\"{tier}\"` (for comparison) "
              f"| {cpu_s * 1e3:.1f} ms CPU ({wall_s * 1e3:.1f} ms wall) | |")
    print(f"| simulator through the Python iterator (`speed=None`) | {sets_per_s:,.0f} sample sets/s "
          f"| |")
    print(f"| the same in device time per wall-clock time | {real_time_factor:.0f}x real time "
          f"| at least 100x: {met(real_time_factor >= 100.0)} |")
    print(f"| sets missing from the sequence numbers meanwhile | {gaps} "
          f"(device dropped {stats['device_dropped_frames']}) | 0: {met(gaps == 0)} |")
    sys.stdout.flush()


if __name__ == "__main__":
    main()

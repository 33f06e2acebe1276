"""The Python package's performance figures, printed as a markdown table.

1. ``taxel.convert`` of 1,000,000 rows x 4 taxels (one pad) with the default calibration and
   tier, against the fastest vectorised numpy implementation of the same inverse we could
   write (see ``NumpyInverse``): the tare on the first row, dC/C0, and the inverse of the
   default tier's monotone (Fritsch-Carlson) cubic by the model's own method — the interval,
   a chord start, then Newton steps — with every intermediate array allocated once and reused
   (``out=``, in place), the interval found by comparisons (faster than ``np.searchsorted`` for
   a curve of a few points), and the fewest Newton steps that reach the accuracy
   ``taxel.convert`` reaches against an exact (float64, converged) inverse of the same cubic,
   in float64 (float32, as the model computes, is faster but stays above that accuracy:
   the benchmark tries it and says so).
   numpy does less than ``taxel.convert``: no flags, no temperature compensation; the
   comparison favours numpy. (``taxel.convert`` returns pressures and flags, so neither computes
   force, centre of pressure or contact.)
   numpy's arrays are made once, before the timed calls; so, for the goal's ratio, are
   ``taxel.convert``'s (``out=``): both then time the conversion, not allocating and first
   touching new memory. The table also gives ``taxel.convert`` making new arrays each call
   (its default), and the ratio for that.
2. The runs are paired — ``taxel.convert`` then numpy, then the next pair — in one process, on
   one core (``sched_setaffinity``; numpy's element-wise operations are single-threaded too),
   and the table gives the medians of the pairs and the median of the per-pair ratios, with
   the machine's load average before and after. CPU time is the calling thread's
   (``time.thread_time``: both run on it); wall-clock time also counts waiting for a core.
3. The simulated device's sample sets per second through the Python iterator
   (``for sample in taxel.Simulator(speed=None)``), and how many times real time that is.

Regenerate: ``pip install ./python && python python/benchmarks/convert_bench.py >
python/PERFORMANCE.md`` (with a release build: ``maturin develop --release``).
Goals: convert at least 5x faster than numpy and under 100 ms CPU; the iterator at least 100x
real time.
"""

import argparse
import functools
import json
import os
import platform
import statistics
import sys
import time
from dataclasses import dataclass
from typing import Any, Callable, Dict, List, Tuple

import numpy as np
import numpy.typing as npt

import taxel

ROWS = 1_000_000
TAXELS = 4

Floats = npt.NDArray[np.float64]


def default_curve() -> Tuple[Floats, Floats, float]:
    """The default calibration's first taxel: curve points (pressure, dC/C0) and parasitic pF
    (every taxel of the default is the same)."""
    spec = json.loads(taxel.Calibration.default().to_json())["calibration"]
    first = spec["taxels"][0]
    for other in spec["taxels"][1:]:
        assert other == first, "the benchmark assumes one curve for every taxel"
    pressure = np.array([point["pressure_kpa"] for point in first["points"]], dtype=np.float64)
    change = np.array([point["relative_change"] for point in first["points"]], dtype=np.float64)
    return pressure, change, float(first["parasitic_pf"])


def fritsch_carlson_tangents(xs: Floats, ys: Floats) -> Floats:
    """The model's tangents: three-point mean, zero at a local extremum, limited to the circle
    of radius 3."""
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
    return tangents


class NumpyInverse:
    """The default tier in numpy, as fast as we could make it: per interval the Hermite cubic
    in the unit coordinate ``t`` (``f(t) = y0 + t (c1 + t (c2 + t c3))``, the model's form);
    the reading's interval by comparisons with the curve's points; the coefficients gathered with ``np.take``;
    the chord start ``(y - y0) / rise``; ``steps`` Newton steps; the pressure
    ``x0 + width * t``. Every array is allocated once (for ``rows`` x 4) and every operation
    writes into one of them; ``dtype`` float32 halves the memory traffic (the model computes in
    float32 too) when it reaches the accuracy asked for."""

    def __init__(self, pressure: Floats, change: Floats, parasitic_pf: float, rows: int, steps: int,
                 dtype: "type[np.float32] | type[np.float64]" = np.float64):
        tangents = fritsch_carlson_tangents(pressure, change)
        width = np.diff(pressure)
        rise = np.diff(change)
        a = width * tangents[:-1]
        b = width * tangents[1:]
        # One row per interval: y0, c1, c2, c3, 1 / rise, x0, width.
        self.tables = [np.asarray(table, dtype=dtype) for table in (
            change[:-1], a, 3.0 * rise - 2.0 * a - b, a + b - 2.0 * rise, 1.0 / rise,
            pressure[:-1], width)]
        self.inner = np.asarray(change[1:-1], dtype=dtype)
        self.top = dtype(change[-1])
        self.parasitic_pf = parasitic_pf
        self.steps = steps
        self.dtype = dtype
        shape = (rows * TAXELS,)
        self.y = np.empty(shape, dtype=dtype)
        self.t = np.empty(shape, dtype=dtype)
        self.value = np.empty(shape, dtype=dtype)
        self.slope = np.empty(shape, dtype=dtype)
        self.gathered = [np.empty(shape, dtype=dtype) for _ in self.tables]
        self.mask = np.empty(shape, dtype=bool)
        self.counts = np.empty(shape, dtype=np.uint8)

    def __call__(self, capacitance_pf: Floats) -> "npt.NDArray[np.floating[Any]]":
        y, t, value, slope = self.y, self.t, self.value, self.slope
        flat = capacitance_pf.reshape(-1)
        # dC/C0 against the first row (the tare), in place.
        np.subtract(flat, self.parasitic_pf, out=y, casting="same_kind")
        baseline = y[:TAXELS].copy()
        y2 = y.reshape(-1, TAXELS)
        np.divide(y2, baseline, out=y2)
        np.subtract(y, 1.0, out=y, casting="same_kind")
        # The interval of each reading (the count of inner points at or below it: with a few
        # points, comparisons beat np.searchsorted's binary search), and its cubic.
        counts, mask = self.counts, self.mask
        counts.fill(0)
        for point in self.inner:
            np.greater_equal(y, point, out=mask)
            np.add(counts, mask, out=counts, casting="unsafe")
        segment = counts.astype(np.intp)
        y0, c1, c2, c3, inverse_rise, x0, width = self.gathered
        for table, out in zip(self.tables, self.gathered):
            np.take(table, segment, out=out)
        # Chord start, clamped to the interval.
        np.subtract(y, y0, out=y)  # y is now the target relative to the interval's start
        np.multiply(y, inverse_rise, out=t)
        np.clip(t, 0.0, 1.0, out=t)
        for _ in range(self.steps):
            # value = t (c1 + t (c2 + t c3)) - y; slope = c1 + t (2 c2 + 3 t c3)
            np.multiply(t, c3, out=value)
            np.multiply(value, 1.5, out=slope, casting="same_kind")
            np.add(value, c2, out=value)
            np.add(slope, c2, out=slope)
            np.multiply(value, t, out=value)
            np.multiply(slope, t, out=slope)
            np.add(value, c1, out=value)
            np.multiply(slope, 2.0, out=slope, casting="same_kind")
            np.multiply(value, t, out=value)
            np.add(slope, c1, out=slope)
            np.subtract(value, y, out=value)
            np.divide(value, slope, out=value)
            np.subtract(t, value, out=t)
        # The pressure; 0 below the baseline, NaN above the curve and in the tare row.
        np.multiply(t, width, out=t)
        np.add(t, x0, out=t)
        np.add(y, y0, out=y)  # dC/C0 again
        np.less_equal(y, 0.0, out=self.mask)
        np.copyto(t, 0.0, where=self.mask, casting="same_kind")
        np.greater(y, self.top, out=self.mask)
        np.copyto(t, np.nan, where=self.mask, casting="same_kind")
        t[:TAXELS] = np.nan
        return t.reshape(-1, TAXELS)


def exact_inverse(pressure: Floats, change: Floats, readings: Floats) -> Floats:
    """The float64 root of the same cubic, converged (bisection, then Newton to the last bit)."""
    tangents = fritsch_carlson_tangents(pressure, change)
    width = np.diff(pressure)
    rise = np.diff(change)
    a = width * tangents[:-1]
    b = width * tangents[1:]
    c2 = 3.0 * rise - 2.0 * a - b
    c3 = a + b - 2.0 * rise
    segment = np.searchsorted(change[1:-1], readings, side="right")
    y = readings - change[:-1][segment]
    A, C2, C3 = a[segment], c2[segment], c3[segment]
    low, high = np.zeros_like(y), np.ones_like(y)
    for _ in range(30):
        middle = 0.5 * (low + high)
        above = middle * (A + middle * (C2 + middle * C3)) > y
        high = np.where(above, middle, high)
        low = np.where(above, low, middle)
    t = 0.5 * (low + high)
    for _ in range(3):
        t -= (t * (A + t * (C2 + t * C3)) - y) / (A + t * (2.0 * C2 + 3.0 * t * C3))
    return np.asarray(pressure[:-1][segment] + width[segment] * t)


def paired_runs(runs: int, functions: Dict[str, Callable[[], object]]) -> Dict[str, List[Tuple[float, float]]]:
    """(wall, CPU) seconds of each function in each of `runs` rounds, the functions taking
    turns within a round (so a machine whose speed drifts slows them alike)."""
    times: Dict[str, List[Tuple[float, float]]] = {name: [] for name in functions}
    for _ in range(runs):
        for name, function in functions.items():
            wall_started, cpu_started = time.perf_counter(), time.thread_time()
            function()
            cpu_s = time.thread_time() - cpu_started
            wall_s = time.perf_counter() - wall_started
            times[name].append((wall_s, cpu_s))
    return times


def median(values: List[float]) -> float:
    return float(statistics.median(values))


@dataclass
class ConvertFigures:
    """What the conversion measurements found (times in seconds, errors in kPa)."""

    taxel_cpu_s: float
    taxel_wall_s: float
    taxel_min_cpu_s: float
    out_cpu_s: float
    out_wall_s: float
    out_ratio: float
    out_ratios: List[float]
    numpy_cpu_s: float
    numpy_wall_s: float
    ratio: float
    ratios: List[float]
    taxel_error_kpa: float
    numpy_errors_kpa: Dict[str, Dict[int, float]]
    numpy_dtype: str
    steps: int
    compared: float
    tiers: Dict[str, float]


def convert_figures(runs: int) -> ConvertFigures:
    pressure_points, change_points, parasitic_pf = default_curve()
    rng = np.random.default_rng(1)
    applied_kpa = rng.uniform(0.0, 0.9 * pressure_points[-1], (ROWS, TAXELS))
    applied_kpa[0] = 0.0
    # Capacitances of those pressures through the curve (piecewise-linear is enough to make
    # realistic data: both implementations then invert the same numbers), as the float32
    # values a device sends.
    change = np.interp(applied_kpa, pressure_points, change_points)
    capacitance_pf = (parasitic_pf + 4.5 * (1.0 + change)).astype(np.float32).astype(np.float64)
    temperature_c = np.full(ROWS, 25.0)

    taxel_kpa, _ = taxel.convert(capacitance_pf, temperature_c)
    sensor = capacitance_pf - parasitic_pf
    readings = (sensor / sensor[0] - 1.0)[1:]
    inside = (readings > 0.0) & (readings <= change_points[-1])
    exact = np.full(readings.shape, np.nan)
    exact[inside] = exact_inverse(pressure_points, change_points, readings[inside])
    compared = inside & np.isfinite(taxel_kpa[1:])
    taxel_error = float(np.max(np.abs(taxel_kpa[1:][compared] - exact[compared])))

    # The fewest Newton steps with which numpy is at least as accurate as taxel.convert:
    # in float32 (half the memory traffic) if it gets there, else in float64.
    errors: Dict[str, Dict[int, float]] = {}
    chosen = None
    dtypes: "list[type[np.float32] | type[np.float64]]" = [np.float32, np.float64]
    for dtype in dtypes:
        errors[dtype.__name__] = {}
        for steps in range(0, 4):
            candidate = NumpyInverse(pressure_points, change_points, parasitic_pf, ROWS, steps, dtype)
            numpy_kpa = candidate(capacitance_pf)
            error = float(np.max(np.abs(numpy_kpa[1:][compared] - exact[compared])))
            errors[dtype.__name__][steps] = error
            if error <= taxel_error:
                chosen = candidate
                break
        if chosen is not None:
            break
    if chosen is None:
        raise RuntimeError(f"numpy never reached taxel.convert's accuracy: {errors}")
    numpy_inverse = chosen
    steps = numpy_inverse.steps

    out = (np.empty(capacitance_pf.shape), np.empty(capacitance_pf.shape, dtype=np.uint16))
    timed = paired_runs(runs, {
        "taxel": lambda: taxel.convert(capacitance_pf, temperature_c),
        "taxel_out": lambda: taxel.convert(capacitance_pf, temperature_c, out=out),
        "numpy": lambda: numpy_inverse(capacitance_pf),
    })
    assert np.array_equal(out[0], taxel_kpa, equal_nan=True), "out= gave other pressures"

    def ratios_of(name: str) -> List[float]:
        return [numpy_cpu / cpu for (_, cpu), (_, numpy_cpu) in zip(timed[name], timed["numpy"])]

    ratios = ratios_of("taxel")
    out_ratios = ratios_of("taxel_out")
    tiers = paired_runs(max(3, runs // 2), {
        tier: functools.partial(taxel.convert, capacitance_pf, temperature_c, tier=tier)
        for tier in ("linear", "polynomial", "table")
    })
    return ConvertFigures(
        taxel_cpu_s=median([cpu for _, cpu in timed["taxel"]]),
        taxel_wall_s=median([wall for wall, _ in timed["taxel"]]),
        taxel_min_cpu_s=min(cpu for _, cpu in timed["taxel"]),
        out_cpu_s=median([cpu for _, cpu in timed["taxel_out"]]),
        out_wall_s=median([wall for wall, _ in timed["taxel_out"]]),
        out_ratio=median(out_ratios),
        out_ratios=out_ratios,
        numpy_cpu_s=median([cpu for _, cpu in timed["numpy"]]),
        numpy_wall_s=median([wall for wall, _ in timed["numpy"]]),
        ratio=median(ratios),
        ratios=ratios,
        taxel_error_kpa=taxel_error,
        numpy_errors_kpa=errors,
        numpy_dtype=numpy_inverse.dtype.__name__,
        steps=steps,
        compared=float(np.mean(compared)),
        tiers={tier: median([cpu for _, cpu in values]) for tier, values in tiers.items()},
    )


def iterator_figures(seconds: float) -> Tuple[float, float, int, Dict[str, int]]:
    with taxel.Simulator(speed=None) as sim:
        sim.read()
        count, gaps = 0, 0
        first = last = 0
        started = time.perf_counter()
        for sample in sim:
            if count == 0:
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


def met(condition: bool) -> str:
    """A goal's verdict as the table prints it."""
    return "met" if condition else "**not met**"


def main() -> None:
    parser = argparse.ArgumentParser(description="The Python package's performance table")
    parser.add_argument("--runs", type=int, default=9, help="paired runs (at least 5)")
    parser.add_argument("--seconds", type=float, default=3.0, help="iterator measurement, s")
    arguments = parser.parse_args()
    if arguments.runs < 5:
        parser.error("--runs must be at least 5")
    if hasattr(os, "sched_setaffinity"):
        # One core for everything, as the goal says.
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    load_before = os.getloadavg()
    figures = convert_figures(arguments.runs)
    sets_per_s, real_time_factor, gaps, stats = iterator_figures(arguments.seconds)
    load_after = os.getloadavg()
    taxel_cpu_s, numpy_cpu_s, ratio = figures.taxel_cpu_s, figures.numpy_cpu_s, figures.ratio
    print("# The Python package's performance\n")
    print("Generated by `pip install ./python && python python/benchmarks/convert_bench.py > "
          "python/PERFORMANCE.md` (the benchmark's docstring says what it measures and how the "
          "numpy implementation is written); do not edit by hand.\n")
    print(f"Python {platform.python_version()}, numpy {np.__version__}, {platform.machine()}, "
          f"one core of {os.cpu_count()}; medians of {arguments.runs} paired runs in one process; "
          f"load average (1, 5, 15 min) {load_before[0]:.2f}, {load_before[1]:.2f}, "
          f"{load_before[2]:.2f} before and {load_after[0]:.2f}, {load_after[1]:.2f}, "
          f"{load_after[2]:.2f} after: a load above 1 per core means the runs shared their core "
          "with other work, which inflates wall-clock times more than CPU times.\n")
    print("| measurement | value | goal |")
    print("|---|---|---|")
    print(f"| `taxel.convert`, {ROWS:,} rows x {TAXELS} taxels (default calibration and tier; the "
          f"host library's conversion engine) | {taxel_cpu_s * 1e3:.1f} ms CPU "
          f"({figures.taxel_wall_s * 1e3:.1f} ms wall; fastest run {figures.taxel_min_cpu_s * 1e3:.1f} ms CPU) "
          f"| under 100 ms: {met(taxel_cpu_s < 0.1)} |")
    print(f"| the same into arrays made once (`out=`) | {figures.out_cpu_s * 1e3:.1f} ms CPU "
          f"({figures.out_wall_s * 1e3:.1f} ms wall) | |")
    print(f"| numpy, the same inverse vectorised in place (its arrays made once), {figures.numpy_dtype}, "
          f"{figures.steps} Newton step(s) "
          f"| {numpy_cpu_s * 1e3:.1f} ms CPU ({figures.numpy_wall_s * 1e3:.1f} ms wall) | |")
    print(f"| numpy time / `taxel.convert` time, both into arrays made once (CPU, median of the "
          f"pairs' ratios) | {figures.out_ratio:.2f}x "
          f"(pairs: {', '.join(f'{value:.2f}' for value in figures.out_ratios)}) "
          f"| at least 5x: {met(figures.out_ratio >= 5.0)} |")
    print(f"| the same with `taxel.convert` making new arrays each call | {ratio:.2f}x "
          f"(pairs: {', '.join(f'{value:.2f}' for value in figures.ratios)}) | |")
    print(f"| largest error against the exact inverse (float64, converged), over "
          f"{figures.compared:.1%} of the values | `taxel.convert` {figures.taxel_error_kpa:.2g} kPa; numpy "
          + "; ".join(
              f"{dtype}: " + ", ".join(f"{steps} step(s) {error:.2g} kPa" for steps, error in by_steps.items())
              for dtype, by_steps in figures.numpy_errors_kpa.items())
          + " | numpy at least as accurate |")
    for tier, cpu_s in figures.tiers.items():
        print(f"| `taxel.convert` with `tier=\"{tier}\"` (for comparison) | {cpu_s * 1e3:.1f} ms CPU | |")
    print(f"| simulator through the Python iterator (`speed=None`) | {sets_per_s:,.0f} sample sets/s | |")
    print(f"| the same in device time per wall-clock time | {real_time_factor:.0f}x real time "
          f"| at least 100x: {met(real_time_factor >= 100.0)} |")
    print(f"| sets missing from the sequence numbers meanwhile | {gaps} "
          f"(device dropped {stats['device_dropped_frames']}) | 0: {met(gaps == 0)} |")
    sys.stdout.flush()


if __name__ == "__main__":
    main()

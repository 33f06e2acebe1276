"""A researcher's first hour with the pad, against the simulated device: stream, look, save,
convert again, fit a calibration.

    python examples/first_hour.py                    # 50 s of the demo scene at 20x real time
    python examples/first_hour.py --plot first.png   # and a plot (needs matplotlib)

1. Stream the demo scene (a light press, a press sliding across the pad, the whole pad at
   50 kPa, then 20 kPa while the pad warms) into a background buffer, with the device's events.
2. Summarise: sets, losses, force, where the contact is (centre of pressure), contact events.
3. Save the buffer as a recording (the file ``taxel record`` writes), read it back, as pandas.
4. Convert it again with another tier, as ``taxel convert --tier`` would.
5. Fit a calibration from the scene's known plateaus (0, 50 and 20 kPa) and convert with it.

With a board attached, use ``taxel.Device()`` instead of ``taxel.Simulator(...)``.
"""

import argparse
import time

import numpy as np
import numpy.typing as npt

import taxel

# The demo scene's plateaus (sim-device/scenes/default.toml): seconds of device time, and the
# pressure every taxel then feels.
PLATEAUS = [((1.0, 2.8), 0.0), ((24.3, 26.8), 50.0), ((32.2, 33.5), 20.0)]


def plateau_rows(device_s: "npt.NDArray[np.float64]") -> "list[tuple[npt.NDArray[np.bool_], float]]":
    """The rows of each plateau, with its pressure."""
    return [((device_s > start) & (device_s < end), kpa) for (start, end), kpa in PLATEAUS]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--speed", type=float, default=20.0, help="simulated seconds per second")
    parser.add_argument("--seconds", type=float, default=2.5, help="wall-clock seconds to stream")
    parser.add_argument("--output", default="first_hour.csv", help="where to save the recording")
    parser.add_argument("--plot", default=None, help="save a plot here (needs matplotlib)")
    arguments = parser.parse_args()

    # 1. Stream.
    with taxel.Simulator(speed=arguments.speed) as device:
        print(f"device {device.info['board_serial']}: {device.pads} pad, tier {device.info['tier']}, "
              f"{device.info['rate_sps']} conversions/s")
        device.start_buffering()
        time.sleep(arguments.seconds)
        buffer = device.read_buffer()  # raises taxel.DataLossError if any set was lost
        events = device.events()

    # 2. Summarise.
    device_s = buffer.device_time_us / 1e6
    span_s = device_s[-1] - device_s[0]
    print(f"{len(buffer)} sample sets over {span_s:.1f} s of device time "
          f"({len(buffer) / span_s:.0f} sets/s), {buffer.lost_sets} lost")
    force = buffer.force_n[:, 0]
    print(f"force: up to {np.nanmax(force):.2f} N; in contact {buffer.contact[:, 0].mean():.0%} of the time")
    sliding = (device_s > 9.0) & (device_s < 15.0) & buffer.contact[:, 0]
    if sliding.any():
        path = buffer.cop_mm[sliding, 0]
        print(f"the sliding press: centre of pressure from ({path[0, 0]:+.2f}, {path[0, 1]:+.2f}) mm "
              f"to ({path[-1, 0]:+.2f}, {path[-1, 1]:+.2f}) mm")
    for event in events:
        print(f"  {event.device_time_s:7.3f} s  {event.kind:<18} pad {event.pad}  {event.fields or ''}")

    # 3. Save, read back, look at it with pandas.
    buffer.save(arguments.output)
    recording = taxel.read_recording(arguments.output)
    assert np.array_equal(recording.pressure_kpa, buffer.pressure_kpa, equal_nan=True)
    try:
        table = recording.to_pandas()
    except ImportError as error:
        print(f"(no pandas: {error})")
    else:
        summary = table.groupby("contact")[["force_n", "p11_kpa"]].mean()
        print(f"saved {len(table)} rows to {arguments.output}; mean force and p11 by contact:")
        print(summary.to_string(float_format=lambda value: f"{value:.3f}"))

    # 4. Convert again with another tier. A saved buffer has no device state beside it (what
    # `taxel record` writes for an exact re-conversion): tare on the first 16 rows, as the
    # device's own tare at boot.
    linear = taxel.convert_recording(arguments.output, tier="linear", tare_rows=16, use_device_state=False)
    both = np.isfinite(linear.pressure_kpa) & np.isfinite(recording.pressure_kpa)
    difference = np.abs(linear.pressure_kpa - recording.pressure_kpa)[both]
    print(f"tier linear against the device's monotone-cubic: up to {difference.max():.2f} kPa apart "
          f"(median {np.median(difference):.3f} kPa)")

    # 5. Fit a calibration from the known plateaus, and convert with it.
    rows = plateau_rows(device_s)
    if any(not chosen.any() for chosen, _ in rows):
        print("the stream did not reach every plateau: stream longer (--seconds) or faster (--speed)")
        return
    pressure_kpa = np.concatenate([np.full(chosen.sum(), kpa) for chosen, kpa in rows])
    capacitance_pf = np.concatenate([buffer.capacitance_pf[chosen] for chosen, _ in rows])
    temperature_c = np.concatenate([buffer.temperature_c[chosen, 0] for chosen, _ in rows])
    calibration = taxel.Calibration.fit(pressure_kpa, capacitance_pf, temperature_c, id=42)
    print(calibration.fit_report.splitlines()[0] if calibration.fit_report else "")
    refit, _ = taxel.convert(buffer.capacitance_pf, buffer.temperature_c, calibration=calibration, tare_rows=16)
    for chosen, kpa in rows[1:]:
        print(f"  {kpa:4.0f} kPa plateau: device {np.nanmean(buffer.pressure_kpa[chosen]):6.2f} kPa, "
              f"fitted calibration {np.nanmean(refit[chosen]):6.2f} kPa")

    if arguments.plot:
        plot(arguments.plot, device_s, buffer)


def plot(path: str, device_s: "npt.NDArray[np.float64]", buffer: taxel.Buffer) -> None:
    """Pressure per taxel, force and centre of pressure against device time."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: pip install matplotlib to get the plot")
        return
    figure, axes = plt.subplots(3, 1, sharex=True, figsize=(9, 7))
    for k, name in enumerate(["C11", "C12", "C21", "C22"]):
        axes[0].plot(device_s, buffer.pressure_kpa[:, k], label=name, linewidth=0.8)
    axes[0].set_ylabel("kPa")
    axes[0].legend(loc="upper right", ncol=4, fontsize="small")
    axes[1].plot(device_s, buffer.force_n[:, 0], linewidth=0.8)
    axes[1].set_ylabel("force, N")
    axes[2].plot(device_s, buffer.cop_mm[:, 0, 0], label="x", linewidth=0.8)
    axes[2].plot(device_s, buffer.cop_mm[:, 0, 1], label="y", linewidth=0.8)
    axes[2].set_ylabel("centre, mm")
    axes[2].legend(loc="upper right", fontsize="small")
    axes[-1].set_xlabel("device time, s")
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()

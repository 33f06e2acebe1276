"""Records 10 s from the simulated device and plots every taxel's pressure (with matplotlib,
when it is installed; otherwise prints a summary).

    python examples/record_simulator.py                 # 10 s of the demo scene, real time
    python examples/record_simulator.py --scene gripper --seconds 5 --speed 4 --output grip.png

With a board attached, use ``taxel.Device()`` instead of ``taxel.Simulator(...)``: everything
else stays the same.
"""

import argparse
import time

import numpy as np

import taxel


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="wall-clock seconds to record")
    parser.add_argument("--speed", type=float, default=1.0, help="simulated seconds per second")
    parser.add_argument("--scene", default=None, help="default, gripper, glove or a TOML file")
    parser.add_argument("--output", default="recording.png", help="where to save the plot")
    parser.add_argument("--no-plot", action="store_true", help="print a summary only")
    arguments = parser.parse_args()

    with taxel.Simulator(scene=arguments.scene, speed=arguments.speed) as device:
        print(f"recording {arguments.seconds} s from {device.info['board_serial']} "
              f"({device.pads} pad(s), tier {device.info['tier']})")
        device.start_buffering()
        time.sleep(arguments.seconds)
        buffer = device.read_buffer()  # raises taxel.DataLossError if any set was lost

    time_s = (buffer.device_time_us - buffer.device_time_us[0]) / 1e6
    pressure = buffer.pressure_kpa.reshape(len(buffer), buffer.pads, 4)
    print(f"{len(buffer)} sample sets over {time_s[-1]:.2f} s of device time, none lost; "
          f"highest pressure {np.nanmax(pressure):.1f} kPa")

    if arguments.no_plot:
        return
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: pip install matplotlib to get the plot")
        return
    figure, axes = plt.subplots(buffer.pads, 1, sharex=True, squeeze=False,
                                figsize=(9, 2.2 * buffer.pads + 1))
    for pad in range(buffer.pads):
        axis = axes[pad, 0]
        for taxel_index, name in enumerate(["C11", "C12", "C21", "C22"]):
            axis.plot(time_s, pressure[:, pad, taxel_index], label=name, linewidth=0.8)
        axis.set_ylabel(f"pad {pad}\nkPa")
        axis.legend(loc="upper right", fontsize="small", ncol=4)
    axes[-1, 0].set_xlabel("device time, s")
    figure.tight_layout()
    figure.savefig(arguments.output, dpi=120)
    print(f"wrote {arguments.output}")


if __name__ == "__main__":
    main()

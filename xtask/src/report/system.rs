//! The firmware's flash and RAM, and the simulator's throughput and latency.

use super::*;

pub(super) fn firmware(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## Firmware flash and RAM\n");
    let footprint = match &data.firmware {
        Ok(footprint) => footprint,
        Err(reason) => {
            let _ = writeln!(
                out,
                "Not available: the firmware did not build ({reason}).\n"
            );
            return;
        }
    };
    let percent = |used: u64, budget: u64| 100.0 * used as f64 / budget as f64;
    let _ = writeln!(
        out,
        "Built by `cargo fw-build` (profile `firmware`, opt-level {} from `[profile.firmware]` \
         in Cargo.toml, model-core at opt-level {}; ELF `{}` in the target directory), measured \
         as `.ci/firmware-size` measures it.\n",
        footprint.opt_level, footprint.model_core_opt_level, footprint.path
    );
    let _ = writeln!(
        out,
        "| | bytes | budget | used | within |\n|---|---|---|---|---|\n\
         | flash (vector table, code, constants, .data initialisers) | {} | {} ({} KiB) | {:.1} % | {} |\n\
         | static RAM (.data, .bss, .uninit; the stack comes on top) | {} | {} ({} KiB) | {:.1} % | {} |\n",
        footprint.flash_bytes,
        FLASH_BUDGET_BYTES,
        FLASH_BUDGET_BYTES / 1024,
        percent(footprint.flash_bytes, FLASH_BUDGET_BYTES),
        if footprint.flash_bytes <= FLASH_BUDGET_BYTES {
            "yes"
        } else {
            "**no**"
        },
        footprint.ram_bytes,
        STATIC_RAM_BUDGET_BYTES,
        STATIC_RAM_BUDGET_BYTES / 1024,
        percent(footprint.ram_bytes, STATIC_RAM_BUDGET_BYTES),
        if footprint.ram_bytes <= STATIC_RAM_BUDGET_BYTES {
            "yes"
        } else {
            "**no**"
        },
    );
    let _ = writeln!(
        out,
        "| section | address | bytes | counted in |\n|---|---|---|---|"
    );
    for section in &footprint.sections {
        let counted = match (section.writable, section.no_bits) {
            (false, _) => "flash",
            (true, false) => "flash (initial values) and RAM",
            (true, true) => "RAM",
        };
        let _ = writeln!(
            out,
            "| `{}` | {:#010x} | {} | {counted} |",
            section.name, section.address, section.size
        );
    }
    let _ = writeln!(
        out,
        "\nWithin both budgets: {}.\n",
        if footprint.within_budget() {
            "yes"
        } else {
            "**no**"
        }
    );
}

/// Bulk payload a full-speed USB device can move at most: 19 transactions of 64 bytes per
/// 1 ms frame (USB 2.0 specification, table 5-10 for full-speed bulk).
const FULL_SPEED_BULK_BYTES_PER_S: u64 = 19 * 64 * 1000;

/// The sample-set rate per pad count on the simulated bus, and the link load of sample frames.
pub(super) fn several_pads(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## Several pads: sample-set rate and USB bandwidth\n");
    match &data.pad_rates {
        Ok(rates) => out.push_str(&crate::pad_rates::table(rates)),
        Err(reason) => {
            let _ = writeln!(out, "Rate per pad count not available: {reason}\n");
        }
    }
    let frame_bytes = wire::SampleFrame::MAX_ENCODED_LEN as u64;
    let packet_bytes = wire::USB_FULL_SPEED_PACKET_LEN as u64;
    let packets_per_frame = frame_bytes.div_ceil(packet_bytes);
    let _ = writeln!(
        out,
        "USB bandwidth, computed: every pad sends one sample frame per sample set, at most \
         {frame_bytes} bytes ({packets_per_frame} packets of at most {packet_bytes} bytes), at \
         the converter's 400 conversions/s = 100 sample sets/s (four conversions per set). A \
         full-speed bulk endpoint moves at most {FULL_SPEED_BULK_BYTES_PER_S} bytes/s (19 \
         packets of 64 bytes per 1 ms frame); events, counters and replies are a few frames per \
         second on top.\n"
    );
    let _ = writeln!(
        out,
        "| pads | sample frames/s | bytes/s, worst case | packets/s, worst case | share of \
         full-speed bulk |\n|---|---|---|---|---|"
    );
    for pads in [1u64, 2, 4, 6, 8] {
        let frames_per_s = pads * 100;
        let bytes_per_s = frames_per_s * frame_bytes;
        let _ = writeln!(
            out,
            "| {pads} | {frames_per_s} | {bytes_per_s} | {} | {:.1} % |",
            frames_per_s * packets_per_frame,
            100.0 * bytes_per_s as f64 / FULL_SPEED_BULK_BYTES_PER_S as f64
        );
    }
    let _ = writeln!(
        out,
        "\nThe device never waits for the host: a frame that does not fit its output queue is \
         dropped and counted (`dropped_sample_frames`), so a slow host costs sample sets, never \
         the acquisition's timing.\n"
    );
}

pub(super) fn microseconds(nanoseconds: f64) -> String {
    format!("{:.2}", nanoseconds / 1000.0)
}

pub(super) fn latency_row(what: &str, latency: &Latency) -> String {
    format!(
        "| {what} | {} | {} | {} | {} | {} |",
        latency.count,
        microseconds(latency.mean_ns),
        microseconds(latency.p50_ns),
        microseconds(latency.p99_ns),
        microseconds(latency.max_ns),
    )
}

pub(super) fn simulator(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## Simulator throughput and latency\n");
    let figures = match &data.simulator {
        Ok(figures) => figures,
        Err(reason) => {
            let _ = writeln!(out, "Not available: {reason}\n");
            return;
        }
    };
    let _ = writeln!(
        out,
        "The simulated device (`sim_device::SimulatedDevice`: the firmware's acquisition loop, \
         model, device application and protocol code on the simulated FDC1004 and TMP117, \
         default scene, seed {}) stepped as fast as the host computes, single-threaded, release \
         build (`cargo xtask sim-bench`, `xtask/src/simulator.rs`). The host port says a host is \
         connected and encodes every outgoing frame with `device::encode_outgoing`, as the \
         firmware's USB task does. {} steps after {} unmeasured ones (boot, converter \
         initialisation, start-up tare).\n",
        crate::simulator::SEED,
        figures.steps,
        crate::simulator::WARM_UP_STEPS,
    );
    let _ = writeln!(
        out,
        "| throughput | |\n|---|---|\n\
         | sample sets per second, wall clock | {:.0} ({:.3} s for {} sets) |\n\
         | sample sets per second, thread CPU time | {:.0} ({:.3} s) |\n\
         | simulated time covered | {:.2} s ({:.0}x real time, wall clock) |\n\
         | frames encoded | {} ({} sample frames, the rest counters and events), {} bytes |\n\
         | simulated I2C transactions per sample set | {:.1} |\n",
        figures.sets_per_second_wall(),
        figures.wall_seconds,
        figures.steps,
        figures.sets_per_second_cpu(),
        figures.cpu_seconds,
        figures.simulated_seconds,
        figures.simulated_seconds / figures.wall_seconds,
        figures.frames,
        figures.sample_frames,
        figures.bytes,
        figures.transactions_per_step,
    );
    let _ = writeln!(
        out,
        "| latency, µs (wall clock) | sets | mean | p50 | p99 | max |\n|---|---|---|---|---|---|\n{}\n{}\n",
        latency_row(
            "converter cycle to encoded frame (live): from the device's last host-side call \
             before the cycle (`HostPort::try_receive`) to the end of `encode_outgoing` of the \
             step's sample frame",
            &figures.cycle_to_frame
        ),
        latency_row(
            "converter results to encoded frame (replay): `PadModel::process` of the step's \
             readings, `device::sample_frame` and `encode_outgoing`",
            &figures.model_to_frame
        ),
    );
    let _ = writeln!(
        out,
        "The live interval contains the whole converter cycle on the simulated bus: the \
         simulated converter and temperature sensor compute their answers on the host, and no \
         time passes on a real bus. The replay interval is the part after the readings are in: \
         before each step a copy of the pad model is taken, and after it the step's readings go \
         through the copy again, then into a frame and its encoding; {} of {} replayed frames \
         differed from the step's own, byte for byte. On the firmware the latency from a \
         converter sample to its frame is dominated by the I2C transfers (the converter's \
         results and the temperature: {:.1} transactions per sample set here), which this \
         measurement does not compute; only the computation after them is comparable, and the \
         M4's instruction counts above are the better guide to it. The maxima include whatever \
         the host's scheduler did meanwhile (wall clock on {} logical CPUs, load average {} \
         before criterion ran).\n",
        figures.replay_mismatches,
        figures.model_to_frame.count,
        figures.transactions_per_step,
        data.machine.cpus,
        data.machine.load_average,
    );
}

/// The tables that other programs generate (the bridge's Python subscriber, the Python package's
/// benchmark), copied from their files so that every measured figure is in this document; each
/// says the command that regenerates it. The report does not run them: they need a Python
/// virtual environment with packages from PyPI.
pub(super) fn measured_elsewhere(out: &mut String) {
    let _ = writeln!(out, "## Measured by their own programs\n");
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    for (what, path) in [
        (
            "The Zenoh / ROS 2 bridge (16 pads bridged on loopback to a Python subscriber; its fault scenarios are in its page)",
            "bridge/PERFORMANCE.md",
        ),
        (
            "The Python package (conversion against numpy, the simulator through the iterator)",
            "python/PERFORMANCE.md",
        ),
        (
            "`taxel convert`'s engine against a reference CSV pass (1,000,000 rows, one core)",
            "host/PERFORMANCE.md",
        ),
    ] {
        let _ = writeln!(out, "### {what}\n");
        match std::fs::read_to_string(root.join(path)) {
            Ok(text) => {
                let regenerate: Vec<&str> = text
                    .lines()
                    .skip_while(|line| !line.starts_with("Generated by"))
                    .take_while(|line| !line.trim().is_empty())
                    .collect();
                let regenerate = regenerate.join(" ");
                let _ = writeln!(out, "From [{path}](../{path}). {regenerate}\n");
                // The page's first table (a page may hold more, such as the bridge's faults).
                for line in text
                    .lines()
                    .skip_while(|line| !line.starts_with('|'))
                    .take_while(|line| line.starts_with('|'))
                {
                    let _ = writeln!(out, "{line}");
                }
                out.push('\n');
            }
            Err(error) => {
                let _ = writeln!(out, "{path} could not be read: {error}\n");
            }
        }
    }
}

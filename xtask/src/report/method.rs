//! How the figures are measured, and the tables of cost, host speed, error and context.

use super::*;

pub(super) fn measurement_method(out: &mut String, data: &ReportData) {
    let run = &data.shipped;
    let noise_relative = CONVERTER_NOISE_PF / NOMINAL_SENSOR_PF;
    let left_out: Vec<String> = data
        .leave_one_out
        .iter()
        .find_map(|(_, loo)| loo.as_ref())
        .map(|loo| {
            loo.per_point
                .iter()
                .map(|(pressure, _)| format!("{pressure}"))
                .collect()
        })
        .unwrap_or_default();
    let _ = writeln!(out, "## How it is measured\n");
    let _ = writeln!(
        out,
        "- **On the M4**: `m4-bench/` is a `no_std` binary that runs model-core built for \
         `thumbv7em-none-eabihf` as the firmware is built (opt-level \"{}\", fat LTO, one codegen \
         unit; and again at opt-level {}) on QEMU's `mps2-an386` (Cortex-M4 with FPU): \
         `qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -icount shift=0 \
         -semihosting-config enable=on,target=native -nographic -kernel m4-bench`. With \
         `-icount shift=0` virtual time advances 1 ns per executed instruction and SysTick \
         counts the 25 MHz processor clock, so one tick is exactly 40 instructions: a count is \
         (ticks around N calls - ticks around the same loop with the call replaced by \
         `black_box` of its inputs) x 40 / N. Counts are deterministic (the same binary gives \
         the same figures on any host).\n\
         - **Temperature-corrected inversion** (numerics.md's taxel conversion): \
         `Baseline::relative_change(SplitCapacitance, inverse_permittivity_ratio)` (dC/C0 from \
         the split capacitance, the baseline and the sample's temperature factor) followed by the \
         tier's inverse, called directly as in a build fixed to one tier (`mean` in m4-bench's \
         output), and through `TaxelInverses::pressure_kpa` with the tier chosen at run time \
         (`dispatched`). Over the grid's capacitance readings, {} passes. Its parts are counted \
         alone too: dC/C0 (`Baseline::relative_change`) and the inverse (called directly on the \
         grid's dC/C0 values).\n\
         - **Full model step**: `TaxelModel::convert(tier, ReadingValue, Some(&Baseline), \
         inverse_permittivity_ratio, &FaultThresholds)`: fault classification of the reading and \
         of dC/C0, the temperature-corrected dC/C0, the tier's inverse dispatched on a run-time \
         `Tier`, and the output record with its flags. Mean over the grid ({} passes); min–max \
         over single inputs (whole kPa at 25 °C, {} repetitions each).\n\
         - **`PadModel::process`**: one sample set of four taxels (the grid reading on each), \
         as the firmware calls it: the raw-code decode (`TaxelReading::value`), the temperature \
         resolution (`TemperatureTracker::resolve`, once per set), every taxel's `convert`, the \
         tare and tracking bookkeeping and the output. Counted block by block of one grid \
         temperature, the pad first brought to it in 1 °C steps (uncounted), so that every \
         counted set is the steady state and not the slew after an implausible jump; {} passes \
         over each block. Per taxel = per set / 4.\n\
         - **Grid**: 0–50 kPa in 0.5 kPa steps x 5–55 °C in 5 °C steps ({} readings) of a taxel \
         with C0 = 4.5 pF and 6 pF parasitic, C = Cp + C0 (1 + f(P)) eps(T)/eps(25 °C) from the \
         f64 forward model, quantised to raw FDC1004 codes at CAPDAC 3, tared at 25 °C through \
         `PadModel`.\n\
         - **References** (computed on the host by m4-bench's build script, written to a binary \
         file the target includes): independent f64 implementations of each tier's model from \
         the same calibration points, applied to the f64 dC/C0 of the quantised reading (see \
         m4-bench/build/reference.rs; the reference curve is `reference_curves::ForwardCubic`). \
         **(a) Numerical error** = |M4 - the tier's own reference|; **distance from the default \
         model** = |M4 - the f64 monotone cubic|.\n\
         - **(b) Model-form error**: leave-one-out on the article's Table 1, with model-core on \
         the host: each interior point ({} kPa) is left out, the tier rebuilt from the others \
         predicts it.\n\
         - **(c) Pressure noise**: {:.1} fF rms converter noise on C0 = {} pF is {:.1e} in \
         dC/C0; times the tier's own dP/d(dC/C0) at the pressure (central difference over +-1 \
         sigma, model-core on the host).\n\
         - **Host**: criterion (`model-core/benches/tiers.rs`), the same grid, one thread, \
         converted as a host tool converts a recording (readings from memory, results to \
         memory, model and tier opaque to the compiler once per pass); time per conversion = \
         thread CPU time per pass over the grid / {}. The model holds its tier's inverse and is \
         opaque to the compiler, so every conversion dispatches on the tier, as on the M4.\n\
         - **Cycles** are estimated, not measured (QEMU models no pipeline, and reads DWT \
         CYCCNT as 0). The dynamic instruction mix comes from a QEMU trace of the shipped build \
         (`-d in_asm,exec,nochain` with an address filter on the benchmark loops and what they \
         call; see `xtask/src/mix.rs`); the Cortex-M4 timing tables then bound the cycles \
         (VDIV/VSQRT 14, VMLA/VFMA 3, loads 1–2, taken branches 2–4, LDM/STM 1 + N, +1 when an \
         FP result is used at once). Flash wait states are not modelled; on the STM32F411 the \
         ART accelerator's prefetch and instruction cache hide them in a hot loop.\n",
        run.opt_level,
        data.opt3.opt_level,
        run.grid_repetitions,
        run.grid_repetitions,
        run.single_repetitions,
        run.grid_repetitions,
        run.grid_points,
        left_out.join(", "),
        CONVERTER_NOISE_PF * 1000.0,
        NOMINAL_SENSOR_PF,
        noise_relative,
        run.grid_points,
    );
}

pub(super) fn cost_table(out: &mut String, data: &ReportData) {
    let (z, three) = (&data.shipped.opt_level, &data.opt3.opt_level);
    let _ = writeln!(out, "## Cost per taxel on the M4\n");
    let _ = writeln!(
        out,
        "Instructions; \"{z}\" is the shipped build, {three} the comparison. Corrected inversion: \
         the inverse called directly (through the run-time dispatch). `convert`: grid mean \
         (min–max over single inputs). `process`: `PadModel::process` per taxel (per sample set \
         of four).\n"
    );
    let _ = writeln!(
        out,
        "| tier | corrected inversion, \"{z}\" | {three} | `convert`, \"{z}\" | {three} | `process` per taxel (per set), \"{z}\" | {three} | est. cycles, `convert`, \"{z}\" |\n|---|---|---|---|---|---|---|---|"
    );
    let corrected = |run: &BenchRun, tier: Tier| {
        optional(run.corrected_count(tier).ok(), |count| {
            format!("{:.1} ({:.1})", count.direct, count.dispatched)
        })
    };
    let convert = |run: &BenchRun, tier: Tier| {
        optional(run.convert_count(tier).ok(), |count| {
            format!("{:.1} ({:.1}–{:.1})", count.mean, count.min, count.max)
        })
    };
    let process = |run: &BenchRun, tier: Tier| {
        optional(run.pad_count(tier).ok(), |count| {
            format!("{:.1} ({:.1})", count.per_taxel, count.per_set)
        })
    };
    for tier in Tier::ALL {
        let cycles = data.mix.as_ref().ok().and_then(|mix| {
            lookup(&mix.per_tier, tier)
                .map(|mix| format!("{:.0}–{:.0}", mix.cycles_lower(), mix.cycles_upper()))
        });
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} |",
            tier.name(),
            corrected(&data.shipped, tier),
            corrected(&data.opt3, tier),
            convert(&data.shipped, tier),
            convert(&data.opt3, tier),
            process(&data.shipped, tier),
            process(&data.opt3, tier),
            cycles.unwrap_or_else(|| "n/a".to_string()),
        );
    }
    let _ = writeln!(
        out,
        "\ndC/C0 alone (`Baseline::relative_change`) costs {} instructions at \"{z}\", {} at \
         {three}: the floor under every corrected inversion.\n",
        one_decimal(data.shipped.functions.get("relative-change").copied()),
        one_decimal(data.opt3.functions.get("relative-change").copied()),
    );
}

pub(super) fn host_table(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## Time per conversion on the host\n");
    let _ = writeln!(
        out,
        "| tier | `convert`, ns of CPU time (95 % CI) | M conversions/s | ns, wall clock | inverse alone (`TaxelInverses::pressure_kpa`), ns | batch (`PadModel::process_all`), ns per taxel (M/s) | its inverse alone (`ActiveInverse::pressures_kpa`), ns |\n|---|---|---|---|---|---|---|"
    );
    for figure in figures(data) {
        let wall = lookup(&data.host_convert_wall, figure.tier);
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} |",
            figure.tier.name(),
            optional(figure.host, |host| format!(
                "{:.2} ({:.2}–{:.2})",
                host.nanoseconds, host.lower_nanoseconds, host.upper_nanoseconds
            )),
            optional(figure.host, |host| format!(
                "{:.0}",
                host.per_second() / 1e6
            )),
            optional(wall, |host| format!("{:.2}", host.nanoseconds)),
            optional(lookup(&data.host_inverse, figure.tier), |host| format!(
                "{:.2}",
                host.nanoseconds
            )),
            optional(lookup(&data.host_batch, figure.tier), |host| format!(
                "{:.2} ({:.0})",
                host.nanoseconds,
                host.per_second() / 1e6
            )),
            optional(
                lookup(&data.host_batch_inverse, figure.tier),
                |host| format!("{:.2}", host.nanoseconds)
            ),
        );
    }
    let _ = writeln!(
        out,
        "\nCriterion means of the benchmarking thread's CPU time, so that time slices given to \
         other processes do not count; the wall-clock column is the same benchmark timed by the \
         clock. They depend on the machine and on what else runs on it (load average {} when \
         criterion started, on {} logical CPUs); the M4 counts do not.\n",
        data.machine.load_average, data.machine.cpus
    );
}

pub(super) fn error_table(out: &mut String, data: &ReportData) {
    let _ = writeln!(out, "## Error\n");
    let _ = writeln!(
        out,
        "| tier | (a) numerical, M4: max | rms | worst at | tolerance | from the default model, M4: max | rms | (b) leave-one-out: max | rms | (c) noise at {} kPa |\n|---|---|---|---|---|---|---|---|---|---|",
        NOISE_PRESSURES_KPA.map(|pressure| pressure.to_string()).join(" / ")
    );
    for tier in Tier::ALL {
        let grid = data.shipped.grid_result(tier).ok();
        let loo = data
            .leave_one_out
            .iter()
            .find(|(candidate, _)| *candidate == tier)
            .and_then(|(_, value)| value.as_ref());
        let noise = lookup(&data.noise_kpa, tier);
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            tier.name(),
            optional(grid, |grid| kpa(grid.max_error_kpa)),
            optional(grid, |grid| kpa(grid.rms_error_kpa)),
            optional(grid, |grid| format!(
                "{} kPa, {} °C",
                grid.worst_at_kpa, grid.worst_at_c
            )),
            optional(grid, |grid| kpa(grid.tolerance_kpa)),
            optional(grid, |grid| kpa(grid.max_from_reference_curve_kpa)),
            optional(grid, |grid| kpa(grid.rms_from_reference_curve_kpa)),
            optional(loo, |loo| kpa(loo.max_kpa)),
            optional(loo, |loo| kpa(loo.rms_kpa)),
            optional(noise, |[low, middle, high]| format!(
                "{} / {} / {}",
                kpa(low),
                kpa(middle),
                kpa(high)
            )),
        );
    }
    let _ = writeln!(
        out,
        "\nAll figures in kPa. (a) and the distance from the default model are over the {}-point \
         grid on the M4 in the shipped build, opt-level \"{}\" (opt-level {} gives {}). \
         Leave-one-out errors per left-out point ({} kPa):\n",
        data.shipped.grid_points,
        data.shipped.opt_level,
        data.opt3.opt_level,
        same_results_text(data),
        data.leave_one_out
            .iter()
            .find_map(|(_, loo)| loo.as_ref())
            .map(|loo| loo
                .per_point
                .iter()
                .map(|(pressure, _)| format!("{pressure}"))
                .collect::<Vec<_>>()
                .join(" / "))
            .unwrap_or_default()
    );
    for (tier, loo) in &data.leave_one_out {
        let detail = match loo {
            Some(loo) => loo
                .per_point
                .iter()
                .map(|(_, error)| kpa(*error))
                .collect::<Vec<_>>()
                .join(" / "),
            None => "not available (a reduced curve does not support the tier)".to_string(),
        };
        let _ = writeln!(out, "- {}: {}", tier.name(), detail);
    }
    let _ = writeln!(out);
}

pub(super) fn same_results_text(data: &ReportData) -> String {
    let differences: Vec<String> = Tier::ALL
        .into_iter()
        .filter_map(|tier| {
            let shipped = data.shipped.grid_result(tier).ok()?;
            let three = data.opt3.grid_result(tier).ok()?;
            (shipped.max_error_kpa != three.max_error_kpa).then(|| {
                format!(
                    "{} {} vs {}",
                    tier.name(),
                    kpa(shipped.max_error_kpa),
                    kpa(three.max_error_kpa)
                )
            })
        })
        .collect();
    if differences.is_empty() {
        "the same maxima for every tier".to_string()
    } else {
        format!("maxima differ: {}", differences.join("; "))
    }
}

pub(super) fn context_table(out: &mut String, data: &ReportData) {
    let (z, three) = (&data.shipped.opt_level, &data.opt3.opt_level);
    let _ = writeln!(out, "## Where the instructions go\n");
    let _ = writeln!(
        out,
        "The parts of a taxel's conversion counted alone (grid means), and functions for \
         comparison.\n"
    );
    let _ = writeln!(
        out,
        "| subject | M4 instructions, \"{z}\" | {three} | host ns |\n|---|---|---|---|"
    );
    let function_row = |out: &mut String, what: &str, key: &str| {
        let _ = writeln!(
            out,
            "| {what} | {} | {} | |",
            one_decimal(data.shipped.functions.get(key).copied()),
            one_decimal(data.opt3.functions.get(key).copied()),
        );
    };
    function_row(
        out,
        "`TaxelReading::value` (raw-code decode and range checks, per taxel)",
        "reading-value",
    );
    function_row(
        out,
        "`TemperatureTracker::resolve` (once per sample set, steady temperature)",
        "temperature-resolve",
    );
    function_row(
        out,
        "`Baseline::relative_change` (dC/C0 alone)",
        "relative-change",
    );
    function_row(
        out,
        "`PadModel::select_tier_for` (the SetUseCase command: every tier's error on four taxels, gripper use case; once, not per sample)",
        "select-use-case",
    );
    for tier in Tier::ALL {
        let _ = writeln!(
            out,
            "| {} inverse alone, called directly (through `TaxelInverses::pressure_kpa`) | {} | {} | {} |",
            tier.name(),
            optional(data.shipped.inverse_count(tier).ok(), |count| format!(
                "{:.1} ({:.1})",
                count.direct, count.dispatched
            )),
            optional(data.opt3.inverse_count(tier).ok(), |count| format!(
                "{:.1} ({:.1})",
                count.direct, count.dispatched
            )),
            optional(lookup(&data.host_inverse, tier), |host| format!(
                "{:.2}",
                host.nanoseconds
            )),
        );
    }
    let fminf_traced = data
        .mix
        .as_ref()
        .ok()
        .map(|mix| mix.traced_functions.iter().any(|name| name == "fminf"));
    let fminf_note = match fminf_traced {
        Some(true) => "; the traced conversions call it",
        Some(false) => "; not called by the traced conversions",
        None => "",
    };
    function_row(
        out,
        "`TableInverse::pressure_kpa` called directly, a second loop",
        "table-direct",
    );
    function_row(
        out,
        &format!(
            "`f32::min`, for comparison (a call to `fminf`: FPv4-SP has no VMINNM{fminf_note})"
        ),
        "f32-min",
    );
    function_row(out, "libm `logf`, x in [1, 8]", "libm-logf");
    function_row(out, "libm `expf`, x in [-5, 0]", "libm-expf");
    function_row(out, "micromath `ln`, x in [1, 8]", "micromath-ln");
    let _ = writeln!(out);
}

//! Why the targets are missed where they are: instruction-mix differences per tier.

use super::*;

/// Differences of one traced mix from another, by class.
pub(super) struct MixDifference {
    pub(super) instructions: f64,
    pub(super) loads: f64,
    pub(super) words: f64,
    pub(super) multiply_accumulates: f64,
    pub(super) arithmetic: f64,
    pub(super) branches: f64,
    pub(super) divides: f64,
}

impl MixDifference {
    fn between(more: &Mix, less: &Mix) -> Self {
        Self {
            instructions: more.instructions - less.instructions,
            loads: more.single_loads - less.single_loads,
            words: more.multiple_words - less.multiple_words,
            multiply_accumulates: more.fp_multiply_accumulate - less.fp_multiply_accumulate,
            arithmetic: more.fp_arithmetic - less.fp_arithmetic,
            branches: (more.unconditional_branches + more.conditional_branches)
                - (less.unconditional_branches + less.conditional_branches),
            divides: more.fp_divide - less.fp_divide,
        }
    }

    /// Everything but single loads, multiply-accumulates, other FP arithmetic, branches and
    /// divisions: stores, load/store-multiple instructions, compares, moves, FPSCR transfers.
    fn others(&self) -> f64 {
        self.instructions
            - self.loads
            - self.multiply_accumulates
            - self.arithmetic
            - self.branches
            - self.divides
    }

    /// Words read from memory, counting load-multiple words with the single loads.
    fn fetched(&self) -> f64 {
        self.loads + self.words
    }
}

pub(super) fn fast_corrected_gap(out: &mut String, data: &ReportData) {
    let run = &data.shipped;
    let Some((tier, count, distance)) =
        fastest_close(data, &data.shipped, Measure::CorrectedInversion)
    else {
        return;
    };
    let relative_change = run.functions.get("relative-change").copied();
    let linear = Measure::CorrectedInversion.count(run, Tier::Linear);
    let mix = data.mix.as_ref().ok();
    let traced = |tier: Tier| mix.and_then(|mix| lookup(&mix.corrected, tier));
    let target = FAST_TIER_MAX_INSTRUCTIONS;

    if let (Some(relative_change), Some(linear)) = (relative_change, linear) {
        let room = if linear < target {
            format!(
                "{:.1} instructions are left under the target for everything a curve needs \
                 beyond a straight line",
                target - linear
            )
        } else {
            format!(
                "the floor alone is {:.1} above the target, so no tier can meet it with this \
                 dC/C0 and clamp",
                linear - target
            )
        };
        let floor_mix = traced(Tier::Linear)
            .zip(mix.map(|mix| mix.relative_change))
            .map(|(linear_mix, relative_mix)| {
                let difference = MixDifference::between(&linear_mix, &relative_mix);
                format!(
                    " In the trace dC/C0 executes {:.1} instructions ({:.1} loads: the \
                     baseline's fields and the inputs, {:.1} multiply-adds, {:.1} other FP \
                     arithmetic) and the linear inverse adds {:.1}: {:.1} loads (its constants, \
                     and its own address, which the benchmark's `black_box` hides), {:.1} FP \
                     arithmetic (the multiply), {:.1} branches and {:.1} others (the compares, \
                     FPSCR transfers and conditional moves of the clamp).",
                    relative_mix.instructions,
                    relative_mix.single_loads,
                    relative_mix.fp_multiply_accumulate,
                    relative_mix.fp_arithmetic,
                    difference.instructions,
                    difference.loads,
                    difference.arithmetic + difference.multiply_accumulates,
                    difference.branches,
                    difference.others() + difference.divides,
                )
            })
            .unwrap_or_default();
        let _ = writeln!(
            out,
            "- **The floor under every tier** (temperature-corrected inversion). dC/C0 alone \
             (`Baseline::relative_change`: the split-capacitance difference, the temperature \
             factor and their multiply-adds) costs {relative_change:.1} instructions. The linear \
             tier, whose inverse is one multiply and the clamp to 0..top, costs {linear:.1}: \
             {:.1} on top of dC/C0.{floor_mix} No inverse is cheaper than a multiply and the \
             clamp, so {linear:.1} is the floor with this dC/C0 and clamp: {room}. (Every count \
             here includes the round trip through the stack that `black_box` forces on each \
             input; a loop over real readings would not have it.)",
            linear - relative_change,
        );
    }

    let Some(linear) = linear else {
        return;
    };
    let difference = traced(tier)
        .zip(traced(Tier::Linear))
        .map(|(tier_mix, linear_mix)| MixDifference::between(&tier_mix, &linear_mix));
    let trace_text = difference
        .as_ref()
        .map(|difference| {
            format!(
                " In the trace it executes {:+.1} instructions against the linear tier: {:+.1} \
                 single loads and {:+.1} words of load/store-multiple instructions, {:+.1} \
                 multiply-accumulates, {:+.1} other FP arithmetic, {:+.1} divisions, {:+.1} \
                 branches, {:+.1} others.",
                difference.instructions,
                difference.loads,
                difference.words,
                difference.multiply_accumulates,
                difference.arithmetic,
                difference.divides,
                difference.branches,
                difference.others(),
            )
        })
        .unwrap_or_default();
    let _ = writeln!(
        out,
        "- **{}**, the cheapest tier within {FAST_TIER_DISTANCE_KPA} kPa of the default model \
         ({} kPa from it), costs {count:.1}, {:.1} more than the linear tier.{trace_text}",
        tier.name(),
        kpa(distance),
        count - linear,
    );
    if tier != Tier::Polynomial {
        return;
    }
    let Some(difference) = difference else {
        return;
    };
    let degree = POLYNOMIAL_DEGREE as f64;
    let fetched_per_coefficient = difference.fetched() / degree;
    let per_coefficient = (difference.fetched() + difference.multiply_accumulates) / degree;
    // Horner's rule on u (c1 + u (c2 + ... u cD)) needs D - 1 multiply-adds.
    let horner_extra = mix
        .zip(traced(Tier::Polynomial))
        .map(|(mix, polynomial)| {
            polynomial.fp_multiply_accumulate - mix.relative_change.fp_multiply_accumulate
        })
        .map(|horner| (horner, horner - (degree - 1.0)))
        .filter(|(_, extra)| *extra > 0.5);
    let horner_text = horner_extra
        .map(|(horner, _)| {
            format!(
                " Its Horner loop executes {horner:.1} multiply-adds (the trace's minus dC/C0's) \
                 where a degree-{POLYNOMIAL_DEGREE} polynomial without constant term needs {}: it \
                 starts from 0.0, and the compiler must keep the first 0 x u, which is not 0 for \
                 an infinite or NaN u.",
                POLYNOMIAL_DEGREE - 1
            )
        })
        .unwrap_or_default();
    let _ = writeln!(
        out,
        "  Over its {POLYNOMIAL_DEGREE} coefficients that is {per_coefficient:.1} instructions \
         per coefficient: {fetched_per_coefficient:.1} loaded word (the coefficient) and a \
         multiply-add.{horner_text}"
    );

    let _ = writeln!(
        out,
        "- **What would close the gap** (estimates from the figures above, not measured; the \
         choice is model-core's):"
    );
    let verdict = |estimate: f64| {
        if estimate <= target {
            format!("{:.1} under the target", target - estimate)
        } else {
            format!("still {:.1} over the target", estimate - target)
        }
    };
    let fewer = lowest_close_degree(data).map(|(lowest_degree, lowest_distance)| {
        let saved = per_coefficient * (degree - lowest_degree as f64);
        (lowest_degree, lowest_distance, count - saved)
    });
    if let Some((lowest_degree, lowest_distance, estimate)) = fewer {
        let _ = writeln!(
            out,
            "  - *Fewer coefficients, larger error*: the lowest degree whose fit stays within \
             {FAST_TIER_DISTANCE_KPA} kPa of the default model on the article's curve is \
             {lowest_degree} ({} kPa; table \"The polynomial fit by degree\"). At \
             {per_coefficient:.1} instructions per coefficient that is about {estimate:.1} \
             instructions, {}.",
            kpa(lowest_distance),
            verdict(estimate)
        );
    }
    let in_registers = count - difference.fetched();
    let _ = writeln!(
        out,
        "  - *Per-taxel constants kept in registers across the four taxels*: the {:.1} words the \
         polynomial loads more than the linear tier are its constants (coefficients and scale). \
         If the four taxels of a sample set shared one curve, a loop over them could keep these \
         in FP registers (the FPU has {FP_REGISTERS} single-precision registers) and load only \
         the baselines: about {in_registers:.1} instructions per taxel, {}. Each taxel has its \
         own calibration today, so this needs one curve per pad.",
        difference.fetched(),
        verdict(in_registers)
    );
    if let Some((_, extra)) = horner_extra {
        let _ = writeln!(
            out,
            "  - *Horner's rule from the last coefficient* instead of from 0.0: {extra:.1} \
             multiply-add fewer, {}.",
            verdict(count - extra)
        );
    }
    if let Some((lowest_degree, _, estimate)) = fewer {
        let all = estimate
            - fetched_per_coefficient * lowest_degree as f64
            - horner_extra.map_or(0.0, |(_, extra)| extra);
        let _ = writeln!(
            out,
            "  - *All of these*: degree {lowest_degree}, its coefficients in registers{}: about \
             {all:.1} instructions, {}. Below that lies the linear tier's {linear:.1}, which \
             only a cheaper dC/C0 or clamp would lower.",
            if horner_extra.is_some() {
                ", Horner's rule from the last coefficient"
            } else {
                ""
            },
            verdict(all)
        );
    }
}

/// Functions of the trace that LLVM's machine outliner made.
pub(super) fn outlined_functions(mix: &MixReport) -> usize {
    mix.traced_functions
        .iter()
        .filter(|name| name.starts_with("OUTLINED_FUNCTION"))
        .count()
}

pub(super) fn default_corrected_gap(out: &mut String, data: &ReportData) {
    let run = &data.shipped;
    let default = Tier::default();
    let Some(count) = Measure::CorrectedInversion.count(run, default) else {
        return;
    };
    let relative_change = run.functions.get("relative-change").copied();
    let inverse = run.inverse_count(default).ok();
    let parts = relative_change
        .zip(inverse)
        .map(|(relative_change, inverse)| {
            format!(
                " Its parts counted alone: dC/C0 (`Baseline::relative_change`) {relative_change:.1}, \
                 the inverse called directly {:.1} (sum {:.1}; the rest, {:+.1}, is what \
                 inlining the two into one loop saves or adds). The inverse alone is {} the \
                 target{}.",
                inverse.direct,
                relative_change + inverse.direct,
                count - relative_change - inverse.direct,
                if inverse.direct > DEFAULT_TIER_MAX_INSTRUCTIONS {
                    "over"
                } else {
                    "within"
                },
                if inverse.direct > DEFAULT_TIER_MAX_INSTRUCTIONS {
                    format!(
                        " by {:.1}: no cheaper dC/C0 closes the gap",
                        inverse.direct - DEFAULT_TIER_MAX_INSTRUCTIONS
                    )
                } else {
                    format!(
                        ", with {:.1} left for dC/C0 where it takes {relative_change:.1}",
                        DEFAULT_TIER_MAX_INSTRUCTIONS - inverse.direct
                    )
                }
            )
        })
        .unwrap_or_default();
    let traced = data
        .mix
        .as_ref()
        .ok()
        .and_then(|mix| lookup(&mix.corrected, default))
        .map(|mix| {
            format!(
                " In the trace: {:.2} VDIV (14 cycles each), {:.1} multiply-adds, {:.1} other FP \
                 arithmetic, {:.1} loads, {:.1} words of load/store-multiple, {:.1} / {:.1} \
                 branches (always / conditional): a search for the segment, Newton steps on the \
                 cubic (each with a division) and the clamp.",
                mix.fp_divide,
                mix.fp_multiply_accumulate,
                mix.fp_arithmetic,
                mix.single_loads,
                mix.multiple_words,
                mix.unconditional_branches,
                mix.conditional_branches
            )
        })
        .unwrap_or_default();
    let outlined = data
        .mix
        .as_ref()
        .ok()
        .map(outlined_functions)
        .filter(|count| *count > 0)
        .map(|count| {
            format!(
                " The traced code passes through {count} functions made by LLVM's machine \
                 outliner (`OUTLINED_FUNCTION_*`: instruction sequences shared to save flash at \
                 opt-level \"{}\", each reached by a call and left by a return, often with \
                 registers pushed and popped).",
                run.opt_level
            )
        })
        .unwrap_or_default();
    let opt3 = Measure::CorrectedInversion
        .count(&data.opt3, default)
        .map(|three| {
            format!(
                " At opt-level {} the same source costs {three:.1} (inverse alone {}): {:.1} of \
                 the shipped count is the price of optimising for size.",
                data.opt3.opt_level,
                optional(data.opt3.inverse_count(default).ok(), |count| format!(
                    "{:.1}",
                    count.direct
                )),
                count - three
            )
        })
        .unwrap_or_default();
    let _ = writeln!(
        out,
        "- **The default tier's corrected inversion** ({}) costs {count:.1}, {:.1} over the \
         {DEFAULT_TIER_MAX_INSTRUCTIONS:.0}-instruction target.{parts}{traced}{outlined}{opt3}",
        default.name(),
        count - DEFAULT_TIER_MAX_INSTRUCTIONS,
    );
}

pub(super) fn process_gap(out: &mut String, data: &ReportData) {
    let run = &data.shipped;
    let default = Tier::default();
    let (Ok(pad), Ok(convert), Ok(corrected), Ok(inverse)) = (
        run.pad_count(default),
        run.convert_count(default),
        run.corrected_count(default),
        run.inverse_count(default),
    ) else {
        return;
    };
    let (Some(decode), Some(temperature), Some(relative_change)) = (
        run.functions.get("reading-value").copied(),
        run.functions.get("temperature-resolve").copied(),
        run.functions.get("relative-change").copied(),
    ) else {
        return;
    };
    let target = PROCESS_MAX_INSTRUCTIONS_PER_TAXEL;
    let dispatch = corrected.dispatched - corrected.direct;
    let classification = convert.mean - corrected.dispatched;
    let rest = pad.per_taxel - convert.mean - decode - temperature / 4.0;
    let non_inverse = pad.per_taxel - inverse.direct;
    let linear = run.pad_count(Tier::Linear).ok();
    let _ = writeln!(
        out,
        "- **`PadModel::process`** with the default tier costs {:.1} per taxel ({:.1} per set of \
         four), {:.1} over the {target:.0}-instruction target. Its measured parts, per taxel:\n\
         \x20 - raw-code decode (`TaxelReading::value`): {decode:.1};\n\
         \x20 - temperature resolution (`TemperatureTracker::resolve`, once per set): \
         {temperature:.1} per set, {:.1} per taxel;\n\
         \x20 - dC/C0 (`Baseline::relative_change`): {relative_change:.1};\n\
         \x20 - the inverse alone, called directly: {:.1};\n\
         \x20 - the run-time tier dispatch (corrected inversion dispatched minus direct): \
         {dispatch:.1};\n\
         \x20 - classification (reading, short/open, dead band, over-range) and the output record \
         inside `convert` (its count minus the dispatched corrected inversion): \
         {classification:.1};\n\
         \x20 - the rest of `process` (flag merging, tare and tracking bookkeeping, the four \
         outputs and the temperature copied out; per taxel minus `convert`, decode and a \
         quarter of the temperature): {rest:.1}.\n\
         \x20 \n\
         \x20 Everything but the inverse costs {non_inverse:.1} per taxel, so with this inverse \
         the target needs {:.1} instructions removed{}.{} Next step (not built): one pass per \
         taxel from the raw code to a flags word without early returns (a QEMU trace of \
         `process` shows the decode's compares, the flag merging and the default values of \
         the fault outputs, set up on the path every reading takes, as its largest blocks), \
         and the outputs written where they go instead of gathered into arrays and copied out \
         (which on the host cost more, so it needs measuring on both).",
        pad.per_taxel,
        pad.per_set,
        pad.per_taxel - target,
        temperature / 4.0,
        inverse.direct,
        pad.per_taxel - target,
        if non_inverse > target {
            format!(
                "; even with a free inverse the rest is {:.1} over",
                non_inverse - target
            )
        } else {
            String::new()
        },
        linear
            .map(|linear| format!(
                " The linear tier's `process` (an inverse of a multiply and a clamp) costs \
                 {:.1} per taxel.",
                linear.per_taxel
            ))
            .unwrap_or_default(),
    );
    if let Ok(three) = data.opt3.pad_count(default) {
        let _ = writeln!(
            out,
            "  At opt-level {} it costs {:.1} per taxel.",
            data.opt3.opt_level, three.per_taxel
        );
    }
}

pub(super) fn gaps(out: &mut String, data: &ReportData) {
    let missed: Vec<TargetKind> = targets(data)
        .into_iter()
        .filter(|target| !target.met)
        .map(|target| target.kind)
        .collect();
    if missed.is_empty() {
        let _ = writeln!(out, "Every target is met.\n");
        return;
    }
    let _ = writeln!(out, "### Why the missed targets are missed\n");
    let _ = writeln!(
        out,
        "From the measured parts of the cost (SysTick counts in the shipped build, grid means; \
         instruction classes from the trace of the same build). How to remove them is \
         model-core's choice; estimates below are marked as such.\n"
    );
    if missed.contains(&TargetKind::DefaultCorrected) {
        default_corrected_gap(out, data);
    }
    if missed.contains(&TargetKind::FastCorrected) {
        fast_corrected_gap(out, data);
    }
    if missed.contains(&TargetKind::DefaultProcess) {
        process_gap(out, data);
    }
    if missed.contains(&TargetKind::DefaultError) {
        let _ = writeln!(
            out,
            "- **The default tier's numerical error** is above {DEFAULT_TIER_MAX_ERROR_KPA} kPa \
             on the M4: see the error table for where, and the hard cases for which inputs."
        );
    }
    if missed.contains(&TargetKind::Host) {
        let fastest = data
            .host_convert
            .iter()
            .min_by(|a, b| a.1.nanoseconds.total_cmp(&b.1.nanoseconds));
        let _ = writeln!(
            out,
            "- **Host**: the fastest conversion measured here takes {} ns of CPU time \
             ({} M/s); {:.0} M/s needs {:.0} ns. The inverse alone takes {} ns for that tier. \
             The machine matters: the load average was {} on {} logical CPUs when criterion \
             ran. This counts one conversion at a time, as the device makes them; a host \
             converting a recording calls `PadModel::process_all` (the batch target).",
            optional(fastest, |(_, host)| format!("{:.2}", host.nanoseconds)),
            optional(fastest, |(_, host)| format!(
                "{:.0}",
                host.per_second() / 1e6
            )),
            HOST_MIN_CONVERSIONS_PER_SECOND / 1e6,
            1e9 / HOST_MIN_CONVERSIONS_PER_SECOND,
            optional(
                fastest.and_then(|(tier, _)| lookup(&data.host_inverse, *tier)),
                |host| format!("{:.2}", host.nanoseconds)
            ),
            data.machine.load_average,
            data.machine.cpus,
        );
    }
    if missed.contains(&TargetKind::HostBatch) {
        host_batch_gap(out, data);
    }
    let _ = writeln!(out);
}

/// Why the host's batch path misses its target, from its measured parts.
fn host_batch_gap(out: &mut String, data: &ReportData) {
    let default = Tier::default();
    let (Some(batch), Some(inverse), Some(linear)) = (
        lookup(&data.host_batch, default),
        lookup(&data.host_batch_inverse, default),
        lookup(&data.host_batch, Tier::Linear),
    ) else {
        return;
    };
    let target_ns = 1e9 / HOST_MIN_CONVERSIONS_PER_SECOND;
    let rest = if linear.nanoseconds >= target_ns {
        format!(
            "that alone is over the target's {target_ns:.0} ns, so no inverse, however cheap, \
             can meet it: the model still builds every taxel's full output record"
        )
    } else {
        format!(
            "with this inverse the rest would have to cost {:.2} ns",
            target_ns - inverse.nanoseconds
        )
    };
    let _ = writeln!(
        out,
        "- **Host batch path** (`PadModel::process_all`, default tier): {:.2} ns per taxel \
         conversion ({:.1} M/s); {:.0} M/s needs {target_ns:.0} ns. Its parts: the batch \
         inverse alone (`ActiveInverse::pressures_kpa`: per value the grid cell from one \
         division, the seed cubic, the cubic and its slope, and the Newton step's division, \
         sixteen values an instruction with AVX-512, eight with AVX2) {:.2} ns a value; \
         everything else (the temperature set by set, then each taxel over the batch's sets: \
         the raw-code decode, classification, flags and its output record) is about what the \
         linear tier's whole batch costs, {:.2} ns, whose inverse is one multiply: {rest}. \
         Within the batch the default's inverse costs {:.2} ns over the linear tier's, not \
         {:.2}: it runs per taxel on each batch of at most {} sets, whose readings are \
         gathered into a column first and whose answers go back into the output records. \
         Next step: outputs written as columns (pressures, flags) rather than records. \
         Measured and slower: batches of 32 or 256 sets, and a classification eight sets an \
         instruction (AVX2) that still made records.",
        batch.nanoseconds,
        batch.per_second() / 1e6,
        HOST_MIN_CONVERSIONS_PER_SECOND / 1e6,
        inverse.nanoseconds,
        linear.nanoseconds,
        batch.nanoseconds - linear.nanoseconds,
        inverse.nanoseconds,
        model_core::BATCH_SAMPLE_SETS,
    );
}

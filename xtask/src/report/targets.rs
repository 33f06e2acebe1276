//! The report's targets and how far each measurement is from its target.

use super::*;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum TargetKind {
    DefaultError,
    DefaultCorrected,
    FastCorrected,
    DefaultProcess,
    Host,
    HostBatch,
}

pub(super) struct Target {
    pub(super) kind: TargetKind,
    pub(super) what: String,
    pub(super) measure: String,
    pub(super) measured: String,
    pub(super) met: bool,
    pub(super) gap: String,
    pub(super) opt3: String,
}

pub(super) fn instruction_gap(count: f64, target: f64) -> (bool, String) {
    if count <= target {
        (true, format!("{:.1} to spare", target - count))
    } else {
        (
            false,
            format!(
                "missed by {:.1} instructions ({:.2}x the target)",
                count - target,
                count / target
            ),
        )
    }
}

pub(super) fn instruction_target(
    data: &ReportData,
    kind: TargetKind,
    what: String,
    measure: Measure,
    tier: Tier,
    target: f64,
) -> Option<Target> {
    let count = measure.count(&data.shipped, tier)?;
    let detail = |run: &BenchRun| match measure {
        Measure::CorrectedInversion => run
            .corrected_count(tier)
            .ok()
            .map(|count| format!(" ({:.1} through the run-time dispatch)", count.dispatched)),
        Measure::FullStep => run
            .convert_count(tier)
            .ok()
            .map(|count| format!(" ({:.1}–{:.1} over single inputs)", count.min, count.max)),
        Measure::PadProcess => run
            .pad_count(tier)
            .ok()
            .map(|count| format!(" ({:.1} per set of four)", count.per_set)),
    };
    let (met, gap) = instruction_gap(count, target);
    Some(Target {
        kind,
        what,
        measure: measure.label().to_string(),
        measured: format!("{count:.1}{}", detail(&data.shipped).unwrap_or_default()),
        met,
        gap,
        opt3: optional(measure.count(&data.opt3, tier), |count| {
            format!("{count:.1}{}", detail(&data.opt3).unwrap_or_default())
        }),
    })
}

pub(super) fn targets(data: &ReportData) -> Vec<Target> {
    let mut targets = Vec::new();
    let default = Tier::default();
    if let Ok(grid) = data.shipped.grid_result(default) {
        targets.push(Target {
            kind: TargetKind::DefaultError,
            what: format!(
                "default tier ({}): max numerical error on the M4 <= {DEFAULT_TIER_MAX_ERROR_KPA} kPa",
                default.name()
            ),
            measure: format!(
                "largest difference from the f64 reference over the {}-point grid",
                data.shipped.grid_points
            ),
            measured: format!("{} kPa", kpa(grid.max_error_kpa)),
            met: grid.max_error_kpa <= DEFAULT_TIER_MAX_ERROR_KPA,
            gap: format!(
                "{:.0}x margin",
                DEFAULT_TIER_MAX_ERROR_KPA / grid.max_error_kpa.max(1e-12)
            ),
            opt3: optional(data.opt3.grid_result(default).ok(), |grid| {
                format!("{} kPa", kpa(grid.max_error_kpa))
            }),
        });
    }
    targets.extend(instruction_target(
        data,
        TargetKind::DefaultCorrected,
        format!(
            "default tier ({}): <= {DEFAULT_TIER_MAX_INSTRUCTIONS:.0} M4 instructions per \
             temperature-corrected inversion",
            default.name()
        ),
        Measure::CorrectedInversion,
        default,
        DEFAULT_TIER_MAX_INSTRUCTIONS,
    ));
    if let Some((tier, _, distance)) =
        fastest_close(data, &data.shipped, Measure::CorrectedInversion)
    {
        if let Some(mut target) = instruction_target(
            data,
            TargetKind::FastCorrected,
            format!(
                "fastest tier within {FAST_TIER_DISTANCE_KPA} kPa of the default tier: <= \
                 {FAST_TIER_MAX_INSTRUCTIONS:.0} M4 instructions per temperature-corrected \
                 inversion"
            ),
            Measure::CorrectedInversion,
            tier,
            FAST_TIER_MAX_INSTRUCTIONS,
        ) {
            target.measured = format!(
                "{}, {} kPa from the default model: {}",
                tier.name(),
                kpa(distance),
                target.measured
            );
            target.opt3 = optional(
                fastest_close(data, &data.opt3, Measure::CorrectedInversion),
                |(tier, count, _)| format!("{}: {count:.1}", tier.name()),
            );
            targets.push(target);
        }
    }
    targets.extend(instruction_target(
        data,
        TargetKind::DefaultProcess,
        format!(
            "full per-taxel `PadModel::process`, default tier ({}): <= \
             {PROCESS_MAX_INSTRUCTIONS_PER_TAXEL:.0} M4 instructions",
            default.name()
        ),
        Measure::PadProcess,
        default,
        PROCESS_MAX_INSTRUCTIONS_PER_TAXEL,
    ));
    let fastest_host = figures(data)
        .iter()
        .filter_map(|figure| figure.host.map(|host| (figure.tier, host)))
        .min_by(|a, b| a.1.nanoseconds.total_cmp(&b.1.nanoseconds));
    if let Some((tier, host)) = fastest_host {
        let met = host.per_second() >= HOST_MIN_CONVERSIONS_PER_SECOND;
        let close =
            fastest_close(data, &data.shipped, Measure::FullStep).and_then(|(close, _, _)| {
                let host = lookup(&data.host_convert, close)?;
                (close != tier).then(|| {
                    format!(
                        "; {} (on the M4 the fastest `TaxelModel::convert` within \
                         {FAST_TIER_DISTANCE_KPA} kPa of the default): {:.1} M/s",
                        close.name(),
                        host.per_second() / 1e6
                    )
                })
            });
        targets.push(Target {
            kind: TargetKind::Host,
            what: format!(
                "host: >= {:.0} M taxel conversions/s on one core, fastest tier",
                HOST_MIN_CONVERSIONS_PER_SECOND / 1e6
            ),
            measure: "`TaxelModel::convert`, criterion, thread CPU time".to_string(),
            measured: format!(
                "{}: {:.1} M/s ({:.2} ns per conversion){}",
                tier.name(),
                host.per_second() / 1e6,
                host.nanoseconds,
                close.unwrap_or_default()
            ),
            met,
            gap: if met {
                format!(
                    "{:.1}x the target",
                    host.per_second() / HOST_MIN_CONVERSIONS_PER_SECOND
                )
            } else {
                format!(
                    "{:.1} M/s short",
                    (HOST_MIN_CONVERSIONS_PER_SECOND - host.per_second()) / 1e6
                )
            },
            opt3: "(host build)".to_string(),
        });
    }
    if let Some(batch) = lookup(&data.host_batch, default) {
        let met = batch.per_second() >= HOST_MIN_CONVERSIONS_PER_SECOND;
        targets.push(Target {
            kind: TargetKind::HostBatch,
            what: format!(
                "host batch path, default tier ({}): >= {:.0} M taxel conversions/s on one core",
                default.name(),
                HOST_MIN_CONVERSIONS_PER_SECOND / 1e6
            ),
            measure: "`PadModel::process_all` (the whole model of a sample set, per taxel), \
                      criterion, thread CPU time"
                .to_string(),
            measured: format!(
                "{:.1} M/s ({:.2} ns per conversion)",
                batch.per_second() / 1e6,
                batch.nanoseconds
            ),
            met,
            gap: if met {
                format!(
                    "{:.1}x the target",
                    batch.per_second() / HOST_MIN_CONVERSIONS_PER_SECOND
                )
            } else {
                format!(
                    "{:.1} M/s short ({:.2}x the time)",
                    (HOST_MIN_CONVERSIONS_PER_SECOND - batch.per_second()) / 1e6,
                    HOST_MIN_CONVERSIONS_PER_SECOND / batch.per_second()
                )
            },
            opt3: "(host build)".to_string(),
        });
    }
    targets
}

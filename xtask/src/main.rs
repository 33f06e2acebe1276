//! Project automation, run as `cargo xtask <command>` (alias in .cargo/config.toml).
//!
//! - `m4-test`: builds m4-bench for the Cortex-M4F, checks it was linked for QEMU's mps2-an386,
//!   runs it under QEMU with a timeout, fails on any miss against the f64 references and when an
//!   instruction count drifts more than 15 % from `model_core::use_case::MEASURED_INSTRUCTIONS`.
//! - `sim-bench [steps]`: throughput and latency of the simulated device, in a release build.
//! - `report`: the same at opt-level 3 and "s", the instruction-mix trace, criterion on the host,
//!   model-core's own figures, the firmware's footprint and the simulator's figures, written to
//!   docs/PERFORMANCE.md and docs/speed-vs-error.svg.

mod bench_output;
mod elf;
mod firmware;
mod host;
mod m4;
mod mix;
mod report;
mod simulator;
mod svg;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{anyhow, bail, Context, Result};
use model_core::use_case::MEASURED_INSTRUCTIONS;
use model_core::Tier;

use bench_output::BenchRun;

/// Largest accepted relative drift of a measured count from `MEASURED_INSTRUCTIONS`.
pub const DRIFT_TOLERANCE: f64 = 0.15;

const USAGE: &str = "usage: cargo xtask <command>

commands:
  m4-test   build m4-bench, run it on QEMU's Cortex-M4F (mps2-an386), fail on any miss or on an
            instruction count more than 15 % away from model_core::use_case::MEASURED_INSTRUCTIONS
  sim-bench [steps]
            throughput and latency of the simulated device over `steps` sample sets (default
            200000), always in a release build
  report    write docs/PERFORMANCE.md and docs/speed-vs-error.svg (takes minutes: criterion)";

fn main() -> ExitCode {
    let command = std::env::args().nth(1);
    let result = match command.as_deref() {
        Some("m4-test") => m4_test(),
        Some("report") => report(),
        Some("sim-bench") => sim_bench(std::env::args().nth(2).as_deref()),
        Some("help" | "--help" | "-h") => {
            println!("{USAGE}");
            return ExitCode::SUCCESS;
        }
        _ => {
            eprintln!("{USAGE}");
            return ExitCode::from(2);
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::FAILURE
        }
    }
}

fn workspace_root() -> Result<PathBuf> {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .ok_or_else(|| anyhow!("xtask has no parent directory"))
}

/// Builds m4-bench with a profile, checks its memory map, runs it on QEMU and parses the output.
fn run_m4_bench(root: &Path, profile: &str) -> Result<BenchRun> {
    let elf = m4::build(root, profile, &[])?;
    elf::check_mps2_layout(&elf::sections(&elf)?)
        .with_context(|| format!("checking {}", elf.display()))?;
    println!("running m4-bench ({profile}) on qemu-system-arm -machine mps2-an386 -icount shift=0");
    let run = m4::run_qemu(m4::qemu_command(&elf, true))?;
    let parsed = BenchRun::parse(&run.stdout)?;
    if run.status != Some(0) && parsed.passed {
        bail!(
            "m4-bench printed a pass but QEMU exited with {:?}:\n{}",
            run.status,
            run.stderr
        );
    }
    if !run.stderr.trim().is_empty() {
        eprintln!("{}", run.stderr.trim_end());
    }
    Ok(parsed)
}

fn print_summary(run: &BenchRun) {
    println!(
        "\n{:<22} {:>12} {:>12} {:>10} {:>26} {:>9} {:>18}",
        "tier (opt-level 3)",
        "max err kPa",
        "rms err kPa",
        "tolerance",
        "instructions mean (min-max)",
        "constant",
        "corrected inversion"
    );
    for tier in Tier::ALL {
        let grid = run.grid_result(tier).ok();
        let count = run.convert_count(tier).ok();
        let constant = MEASURED_INSTRUCTIONS
            .iter()
            .find(|(candidate, _)| *candidate == tier)
            .map_or(0, |(_, constant)| *constant);
        let corrected = run.corrected_count(tier).ok();
        println!(
            "{:<22} {:>12} {:>12} {:>10} {:>26} {:>9} {:>18}",
            tier.name(),
            grid.map_or("-".to_string(), |grid| format!(
                "{:.2e}",
                grid.max_error_kpa
            )),
            grid.map_or("-".to_string(), |grid| format!(
                "{:.2e}",
                grid.rms_error_kpa
            )),
            grid.map_or("-".to_string(), |grid| format!(
                "{:.0e}",
                grid.tolerance_kpa
            )),
            count.map_or("-".to_string(), |count| format!(
                "{:.1} ({:.1}-{:.1})",
                count.mean, count.min, count.max
            )),
            constant,
            corrected.map_or("-".to_string(), |count| format!(
                "{:.1} ({:.1})",
                count.direct, count.dispatched
            ))
        );
    }
    println!(
        "corrected inversion: Baseline::relative_change and the inverse called directly \
         (through TaxelInverses::pressure_kpa in brackets)"
    );
    let passed = run.hard.iter().filter(|result| result.pass).count();
    println!(
        "hard cases: {passed} of {} case x tier results pass ({} cases)\n",
        run.hard.len(),
        run.cases.len()
    );
}

/// Fails when a tier's measured mean count is more than [`DRIFT_TOLERANCE`] away from its
/// `MEASURED_INSTRUCTIONS` constant (or the constant is missing or zero).
fn check_drift(run: &BenchRun) -> Result<()> {
    let mut drifted = Vec::new();
    let mut suggestion = format!(
        "pub const MEASURED_INSTRUCTIONS: [(Tier, u32); {}] = [\n",
        Tier::ALL.len()
    );
    for tier in Tier::ALL {
        let measured = run.convert_count(tier)?.mean;
        suggestion.push_str(&format!(
            "    (Tier::{tier:?}, {}),\n",
            measured.round() as u32
        ));
        let constant = MEASURED_INSTRUCTIONS
            .iter()
            .find(|(candidate, _)| *candidate == tier)
            .map_or(0, |(_, constant)| *constant);
        let drift = (measured - f64::from(constant)).abs() / f64::from(constant.max(1));
        if constant == 0 {
            drifted.push(format!(
                "{}: measured {measured:.1}, no constant",
                tier.name()
            ));
        } else if drift > DRIFT_TOLERANCE {
            drifted.push(format!(
                "{}: measured {measured:.1}, constant {constant} ({:+.1} %)",
                tier.name(),
                100.0 * (measured / f64::from(constant) - 1.0)
            ));
        }
    }
    suggestion.push_str("];");
    if drifted.is_empty() {
        return Ok(());
    }
    bail!(
        "instruction counts drifted more than {:.0} % from model_core::use_case::MEASURED_INSTRUCTIONS:\n  {}\nIf the change is intended, update model-core/src/use_case.rs to:\n{suggestion}",
        DRIFT_TOLERANCE * 100.0,
        drifted.join("\n  ")
    )
}

fn m4_test() -> Result<()> {
    let root = workspace_root()?;
    m4::qemu_version()?;
    let run = run_m4_bench(&root, "release")?;
    print_summary(&run);
    run.require_pass()?;
    check_drift(&run)?;
    println!("m4-test: every check passed and the instruction counts match MEASURED_INSTRUCTIONS");
    Ok(())
}

fn command_line(program: &str, arguments: &[&str]) -> String {
    std::process::Command::new(program)
        .args(arguments)
        .output()
        .ok()
        .and_then(|output| {
            String::from_utf8(output.stdout)
                .ok()?
                .lines()
                .next()
                .map(str::to_string)
        })
        .unwrap_or_else(|| format!("{program} (version unknown)"))
}

fn machine(root: &Path) -> Result<report::Machine> {
    let rustc = std::process::Command::new("rustc")
        .current_dir(root)
        .arg("--version")
        .output()
        .ok()
        .and_then(|output| String::from_utf8(output.stdout).ok())
        .map(|text| text.trim().to_string())
        .unwrap_or_else(|| command_line("rustc", &["--version"]));
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|text| {
            text.lines()
                .find(|line| line.starts_with("model name"))
                .and_then(|line| line.split_once(':'))
                .map(|(_, model)| model.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".to_string());
    Ok(report::Machine {
        rustc,
        qemu: m4::qemu_version()?,
        cpu,
        cpus: std::thread::available_parallelism().map_or(1, usize::from),
        load_average: load_average(),
    })
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .map(|text| {
            text.split_whitespace()
                .take(3)
                .collect::<Vec<_>>()
                .join(" ")
        })
        .unwrap_or_else(|| "unknown".to_string())
}

fn sim_bench(steps: Option<&str>) -> Result<()> {
    let steps = match steps {
        None => simulator::DEFAULT_STEPS,
        Some(text) => text
            .parse()
            .with_context(|| format!("`{text}` is not a number of steps"))?,
    };
    simulator::command(&workspace_root()?, steps)
}

fn report() -> Result<()> {
    let root = workspace_root()?;
    let machine = machine(&root)?;
    let opt3 = run_m4_bench(&root, "release")?;
    opt3.require_pass().context("opt-level 3")?;
    let opt_s = run_m4_bench(&root, "release-s")?;
    opt_s.require_pass().context("opt-level \"s\"")?;
    if let Err(error) = check_drift(&opt3) {
        eprintln!("warning: {error:#}");
    }

    println!("tracing the instruction mix (m4-bench, instruction-mix build)");
    let mix = m4::build(&root, "release-mix", &["instruction-mix"]).and_then(|elf| {
        let log = m4::target_directory(&root, m4::MANIFEST)?.join("instruction-mix.log");
        mix::trace(&elf, &log)
    });
    let mix = mix.map_err(|error| format!("{error:#}"));
    if let Err(error) = &mix {
        eprintln!("warning: no instruction mix: {error}");
    }

    let firmware = firmware::build_and_measure(&root).map_err(|error| format!("{error:#}"));
    if let Err(error) = &firmware {
        eprintln!("warning: no firmware footprint: {error}");
    }
    let simulator = simulator::run_release(&root, simulator::DEFAULT_STEPS)
        .map_err(|error| format!("{error:#}"));
    if let Err(error) = &simulator {
        eprintln!("warning: no simulator figures: {error}");
    }

    println!("running criterion (cargo bench -p model-core --bench tiers)");
    let mut machine = machine;
    machine.load_average = load_average();
    let criterion_home = m4::target_directory(&root, "Cargo.toml")?.join("criterion");
    host::run_benches(&root, &criterion_home)?;
    let mut host_convert = Vec::new();
    let mut host_convert_wall = Vec::new();
    let mut host_inverse = Vec::new();
    for tier in Tier::ALL {
        host_convert.push((tier, host::read_bench(&criterion_home, "convert", tier)?));
        host_convert_wall.push((
            tier,
            host::read_bench(&criterion_home, "convert-wall", tier)?,
        ));
        host_inverse.push((tier, host::read_bench(&criterion_home, "inverse", tier)?));
    }

    let inverses = host::article_inverses();
    let data = report::ReportData {
        opt3,
        opt_s,
        mix,
        host_convert,
        host_convert_wall,
        host_inverse,
        leave_one_out: Tier::ALL
            .into_iter()
            .map(|tier| (tier, host::leave_one_out(tier)))
            .collect(),
        noise_kpa: Tier::ALL
            .into_iter()
            .map(|tier| {
                (
                    tier,
                    report::NOISE_PRESSURES_KPA
                        .map(|pressure| host::pressure_noise_kpa(&inverses, tier, pressure)),
                )
            })
            .collect(),
        use_cases: host::use_case_selections(),
        polynomial_degrees: host::polynomial_degree_distances(),
        machine,
        firmware,
        simulator,
    };
    let docs = root.join("docs");
    std::fs::create_dir_all(&docs)?;
    std::fs::write(docs.join("PERFORMANCE.md"), report::markdown(&data))?;
    std::fs::write(
        docs.join("speed-vs-error.svg"),
        svg::render(&report::plot(&data)),
    )?;
    println!("wrote docs/PERFORMANCE.md and docs/speed-vs-error.svg");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run_with_counts(counts: &[(Tier, f64)]) -> BenchRun {
        let mut text = String::new();
        for (tier, mean) in counts {
            text.push_str(&format!(
                "count subject=convert tier={} mean={mean} min={mean} max={mean} single_mean={mean}\n",
                tier.name()
            ));
        }
        text.push_str("summary misses=0 result=pass\n");
        BenchRun::parse(&text).unwrap()
    }

    #[test]
    fn counts_at_the_constants_pass_the_drift_check_and_a_20_percent_drift_fails() {
        let at_constants: Vec<(Tier, f64)> = MEASURED_INSTRUCTIONS
            .iter()
            .map(|(tier, constant)| (*tier, f64::from(*constant)))
            .collect();
        assert!(check_drift(&run_with_counts(&at_constants)).is_ok());
        let mut drifted = at_constants.clone();
        drifted[2].1 *= 1.2;
        let message = check_drift(&run_with_counts(&drifted))
            .unwrap_err()
            .to_string();
        assert!(message.contains(drifted[2].0.name()), "{message}");
        assert!(message.contains("MEASURED_INSTRUCTIONS"), "{message}");
    }

    #[test]
    fn a_missing_count_is_an_error() {
        assert!(check_drift(&run_with_counts(&[(Tier::Linear, 10.0)])).is_err());
    }
}

//! Project automation, run as `cargo xtask <command>` (alias in .cargo/config.toml).
//!
//! - `m4-test [--write]`: builds m4-bench for the Cortex-M4F with the firmware's code generation
//!   (opt-level "z", checked against the root `[profile.firmware]`), checks it was linked for
//!   QEMU's mps2-an386, runs it under QEMU with a timeout, fails on any miss against the f64
//!   references (grid, hard cases, hard calibrations), when the measured order of the tiers
//!   differs from `model_core::use_case::MEASURED_INSTRUCTIONS` or a count drifts further than
//!   half the smallest gap between neighbouring tiers. `--write` rewrites the constant instead.
//! - `sim-bench [steps]`: throughput and latency of the simulated device, in a release build.
//! - `report`: the same at opt-level "z" (shipped) and 3, the instruction-mix trace, criterion on
//!   the host, model-core's own figures, the firmware's footprint and the simulator's figures,
//!   written to docs/PERFORMANCE.md and docs/speed-vs-error.svg; rewrites
//!   `MEASURED_INSTRUCTIONS` from the "z" run first when it differs (and runs again on the
//!   rebuilt model-core).

mod bench_output;
mod elf;
mod firmware;
mod host;
mod m4;
mod measured;
mod mix;
mod pad_rates;
mod report;
mod simulator;
mod speed_plot;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{anyhow, bail, Context, Result};
use model_core::use_case::MEASURED_INSTRUCTIONS;
use model_core::Tier;

use bench_output::BenchRun;

/// m4-bench's profile for the tested and counted build: the firmware's code generation.
pub const SHIPPED_PROFILE: &str = "release";
/// m4-bench's profile for the comparison build at opt-level 3.
pub const OPT3_PROFILE: &str = "release-3";

/// Set in the environment of the second `report` run after it rewrote the constant.
const REGENERATED_ENV: &str = "XTASK_REPORT_AFTER_REWRITE";

const USAGE: &str = "usage: cargo xtask <command>

commands:
  m4-test [--write]
            build m4-bench as the firmware is built (opt-level \"z\"), run it on QEMU's
            Cortex-M4F (mps2-an386), fail on any miss against the f64 references, or when the
            order of the tiers by instruction count differs from
            model_core::use_case::MEASURED_INSTRUCTIONS (or a count drifts further than half the
            smallest gap between tiers); --write rewrites that constant from the run instead
  sim-bench [steps]
            throughput and latency of the simulated device over `steps` sample sets (default
            200000), always in a release build
  pad-rates the sample-set rate per pad for 1 to 8 pads at 100 and 400 kHz on the simulated
            bus, as the report's table
  report    rewrite MEASURED_INSTRUCTIONS if it changed, then write docs/PERFORMANCE.md and
            docs/speed-vs-error.svg (takes minutes: criterion)";

fn main() -> ExitCode {
    let command = std::env::args().nth(1);
    let result = match command.as_deref() {
        Some("m4-test") => match std::env::args().nth(2).as_deref() {
            None => m4_test(false),
            Some("--write") => m4_test(true),
            Some(other) => {
                eprintln!("unknown m4-test argument `{other}`\n{USAGE}");
                return ExitCode::from(2);
            }
        },
        Some("report") => report(),
        Some("pad-rates") => {
            pad_rates::measure().map(|rates| print!("{}", pad_rates::table(&rates)))
        }
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

/// Refuses to measure unless m4-bench's tested profile generates code as the firmware's does.
fn check_shipped_profile(root: &Path) -> Result<()> {
    let read = |path: &str| {
        std::fs::read_to_string(root.join(path)).with_context(|| format!("reading {path}"))
    };
    let firmware = firmware::code_generation(&read("Cargo.toml")?, firmware::PROFILE)?;
    let bench = firmware::code_generation(&read(m4::MANIFEST)?, SHIPPED_PROFILE)?;
    if firmware != bench {
        let show = |settings: &[(String, String)]| {
            settings
                .iter()
                .map(|(key, value)| format!("{key} = {value}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        bail!(
            "m4-bench's [profile.{SHIPPED_PROFILE}] ({}) does not generate code as the root \
             [profile.{}] ({}) does: the counts would not be the shipped build's. Make them agree.",
            show(&bench),
            firmware::PROFILE,
            show(&firmware)
        );
    }
    Ok(())
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
        "\n{:<22} {:>11} {:>11} {:>9} {:>13} {:>22} {:>9} {:>14} {:>12}",
        format!("tier (opt-level {})", run.opt_level),
        "max err kPa",
        "rms err kPa",
        "tolerance",
        "corrected inv",
        "convert mean (min-max)",
        "constant",
        "process/taxel",
        "process/set"
    );
    for tier in Tier::ALL {
        let grid = run.grid_result(tier).ok();
        let count = run.convert_count(tier).ok();
        let constant = MEASURED_INSTRUCTIONS
            .iter()
            .find(|(candidate, _)| *candidate == tier)
            .map_or(0, |(_, constant)| *constant);
        let corrected = run.corrected_count(tier).ok();
        let pad = run.pad_count(tier).ok();
        println!(
            "{:<22} {:>11} {:>11} {:>9} {:>13} {:>22} {:>9} {:>14} {:>12}",
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
            corrected.map_or("-".to_string(), |count| format!(
                "{:.1} ({:.1})",
                count.direct, count.dispatched
            )),
            count.map_or("-".to_string(), |count| format!(
                "{:.1} ({:.1}-{:.1})",
                count.mean, count.min, count.max
            )),
            constant,
            pad.map_or("-".to_string(), |pad| format!("{:.1}", pad.per_taxel)),
            pad.map_or("-".to_string(), |pad| format!("{:.1}", pad.per_set)),
        );
    }
    println!(
        "corrected inv: Baseline::relative_change and the inverse called directly (through \
         TaxelInverses::pressure_kpa in brackets); convert: TaxelModel::convert; process: \
         PadModel::process"
    );
    let passed = run.hard.iter().filter(|result| result.pass).count();
    println!(
        "hard cases: {passed} of {} case x tier results pass ({} cases)",
        run.hard.len(),
        run.cases.len()
    );
    match run.calibration_summary {
        Some(summary) => println!(
            "hard calibrations: {} curves, {} dC/C0 probes of the default tier's inverse \
             checked against the f64 reference; {} misses\n",
            summary.curves, summary.probes, summary.misses
        ),
        None => println!("hard calibrations: no result\n"),
    }
}

fn m4_test(write: bool) -> Result<()> {
    let root = workspace_root()?;
    m4::qemu_version()?;
    check_shipped_profile(&root)?;
    let run = run_m4_bench(&root, SHIPPED_PROFILE)?;
    print_summary(&run);
    run.require_pass()?;
    if write {
        if measured::rewrite(&root, &run)? {
            println!(
                "m4-test: every check passed; wrote MEASURED_INSTRUCTIONS in {} from this run",
                measured::USE_CASE_FILE
            );
        } else {
            println!("m4-test: every check passed; MEASURED_INSTRUCTIONS already matches this run");
        }
        return Ok(());
    }
    measured::check_ranking(&run, &MEASURED_INSTRUCTIONS)?;
    measured::check_drift(&run, &MEASURED_INSTRUCTIONS)?;
    println!(
        "m4-test: every check passed; the tiers rank as MEASURED_INSTRUCTIONS does ({}), each \
         count within {:.1} instructions of it",
        measured::order_text(
            &MEASURED_INSTRUCTIONS
                .iter()
                .map(|(tier, value)| (*tier, f64::from(*value)))
                .collect::<Vec<_>>()
        ),
        measured::drift_tolerance(&MEASURED_INSTRUCTIONS)
    );
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

/// Runs `cargo xtask report` again (cargo rebuilds xtask on the rewritten model-core).
fn report_again(root: &Path) -> Result<()> {
    println!(
        "MEASURED_INSTRUCTIONS rewritten in {}: running the report again on the rebuilt model-core",
        measured::USE_CASE_FILE
    );
    m4::run_checked(
        m4::cargo()
            .current_dir(root)
            .args(["xtask", "report"])
            .env(REGENERATED_ENV, "1"),
    )
}

fn report() -> Result<()> {
    let root = workspace_root()?;
    let machine = machine(&root)?;
    check_shipped_profile(&root)?;
    let shipped = run_m4_bench(&root, SHIPPED_PROFILE)?;
    shipped.require_pass().context("opt-level \"z\"")?;
    if measured::from_run(&shipped)? != MEASURED_INSTRUCTIONS {
        if std::env::var_os(REGENERATED_ENV).is_some() {
            bail!(
                "MEASURED_INSTRUCTIONS still differs from the run after it was rewritten: is {} \
                 being edited?",
                measured::USE_CASE_FILE
            );
        }
        measured::rewrite(&root, &shipped)?;
        return report_again(&root);
    }
    let opt3 = run_m4_bench(&root, OPT3_PROFILE)?;
    opt3.require_pass().context("opt-level 3")?;

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
    println!("measuring the sample-set rate per pad count on the simulated bus");
    let pad_rates = pad_rates::measure().map_err(|error| format!("{error:#}"));
    if let Err(error) = &pad_rates {
        eprintln!("warning: no rate per pad count: {error}");
    }
    let simulator = simulator::run_release(&root, simulator::DEFAULT_STEPS)
        .map_err(|error| format!("{error:#}"));
    if let Err(error) = &simulator {
        eprintln!("warning: no simulator figures: {error}");
    }

    println!(
        "running criterion (cargo bench -p model-core --bench tiers --features research-tiers)"
    );
    let mut machine = machine;
    machine.load_average = load_average();
    let criterion_home = m4::target_directory(&root, "Cargo.toml")?.join("criterion");
    host::run_benches(&root, &criterion_home)?;
    let mut host_convert = Vec::new();
    let mut host_convert_wall = Vec::new();
    let mut host_inverse = Vec::new();
    let mut host_batch = Vec::new();
    let mut host_batch_inverse = Vec::new();
    for tier in Tier::ALL {
        host_batch.push((tier, host::read_bench(&criterion_home, "batch", tier)?));
        host_batch_inverse.push((
            tier,
            host::read_bench(&criterion_home, "batch-inverse", tier)?,
        ));
        host_convert.push((tier, host::read_bench(&criterion_home, "convert", tier)?));
        host_convert_wall.push((
            tier,
            host::read_bench(&criterion_home, "convert-wall", tier)?,
        ));
        host_inverse.push((tier, host::read_bench(&criterion_home, "inverse", tier)?));
    }

    let inverses = host::article_inverses();
    let data = report::ReportData {
        shipped,
        opt3,
        mix,
        host_convert,
        host_convert_wall,
        host_inverse,
        host_batch,
        host_batch_inverse,
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
        pad_rates,
    };
    let docs = root.join("docs");
    std::fs::create_dir_all(&docs)?;
    let svg = speed_plot::render_svg(&report::plot(&data))?;
    write_whole_file(&docs.join("PERFORMANCE.md"), &report::markdown(&data))?;
    write_whole_file(&docs.join("speed-vs-error.svg"), &svg)?;
    println!("wrote docs/PERFORMANCE.md and docs/speed-vs-error.svg");
    Ok(())
}

/// Writes `text` to `path` through a temporary file renamed into place, so an interrupted run
/// leaves the previous file, never half of a new one.
fn write_whole_file(path: &Path, text: &str) -> Result<()> {
    let mut file = taxel_host::output_file::OutputFile::create(path)?;
    std::io::Write::write_all(&mut file, text.as_bytes())
        .with_context(|| format!("writing {}", path.display()))?;
    file.commit()?;
    Ok(())
}

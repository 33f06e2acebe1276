//! Building m4-bench for the Cortex-M4F and running it under QEMU (mps2-an386) with a timeout.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};

/// The Cortex-M4F target.
pub const TARGET: &str = "thumbv7em-none-eabihf";

/// m4-bench's manifest, relative to the workspace root.
pub const MANIFEST: &str = "m4-bench/Cargo.toml";

/// Longest a QEMU run may take before it is killed (the whole run takes seconds).
pub const QEMU_TIMEOUT: Duration = Duration::from_secs(300);

/// The cargo that runs this xtask (so the pinned toolchain builds everything).
pub fn cargo() -> Command {
    Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()))
}

/// Runs a command to completion, failing on a non-zero status.
pub fn run_checked(command: &mut Command) -> Result<()> {
    let status = command
        .status()
        .with_context(|| format!("starting {command:?}"))?;
    if !status.success() {
        bail!("{command:?} failed with {status}");
    }
    Ok(())
}

/// The target directory cargo uses for a manifest (honours CARGO_TARGET_DIR and config).
pub fn target_directory(root: &Path, manifest: &str) -> Result<PathBuf> {
    let output = cargo()
        .current_dir(root)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--manifest-path",
        ])
        .arg(manifest)
        .output()
        .context("running cargo metadata")?;
    if !output.status.success() {
        bail!(
            "cargo metadata failed: {}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
    let metadata: serde_json::Value =
        serde_json::from_slice(&output.stdout).context("parsing cargo metadata")?;
    metadata["target_directory"]
        .as_str()
        .map(PathBuf::from)
        .ok_or_else(|| anyhow!("cargo metadata gave no target_directory"))
}

/// Builds m4-bench with a profile (`release`, `release-3`, ...) and features; returns the ELF.
pub fn build(root: &Path, profile: &str, features: &[&str]) -> Result<PathBuf> {
    let mut command = cargo();
    command
        .current_dir(root)
        .args(["build", "--manifest-path", MANIFEST, "--target", TARGET]);
    if profile == "release" {
        command.arg("--release");
    } else {
        command.args(["--profile", profile]);
    }
    if !features.is_empty() {
        command.args(["--features", &features.join(",")]);
    }
    run_checked(&mut command)?;
    let elf = target_directory(root, MANIFEST)?
        .join(TARGET)
        .join(profile)
        .join("m4-bench");
    if !elf.is_file() {
        bail!("the build did not produce {}", elf.display());
    }
    Ok(elf)
}

/// First line of `qemu-system-arm --version`, or an error saying how to install it.
pub fn qemu_version() -> Result<String> {
    let output = Command::new("qemu-system-arm")
        .arg("--version")
        .output()
        .context(
            "qemu-system-arm is not installed (Debian/Ubuntu: apt-get install -y qemu-system-arm)",
        )?;
    Ok(String::from_utf8_lossy(&output.stdout)
        .lines()
        .next()
        .unwrap_or("qemu-system-arm (unknown version)")
        .to_string())
}

/// What a QEMU run left behind.
#[derive(Debug, Clone)]
pub struct QemuRun {
    /// Exit code (semihosting exit: 0 = every check passed).
    pub status: Option<i32>,
    /// Semihosting output.
    pub stdout: String,
    /// QEMU's own messages.
    pub stderr: String,
}

/// The QEMU command for an ELF on the mps2-an386 (Cortex-M4 with FPU), with semihosting.
/// `icount` makes virtual time count instructions (1 ns each), which SysTick then measures.
pub fn qemu_command(elf: &Path, icount: bool) -> Command {
    let mut command = Command::new("qemu-system-arm");
    command.args(["-machine", "mps2-an386", "-cpu", "cortex-m4"]);
    if icount {
        command.args(["-icount", "shift=0"]);
    }
    command
        .args([
            "-semihosting-config",
            "enable=on,target=native",
            "-nographic",
            "-monitor",
            "none",
            "-serial",
            "none",
            "-kernel",
        ])
        .arg(elf);
    command
}

/// Runs a QEMU command, killing it after [`QEMU_TIMEOUT`].
pub fn run_qemu(mut command: Command) -> Result<QemuRun> {
    let mut child = command
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .context("starting qemu-system-arm (Debian/Ubuntu: apt-get install -y qemu-system-arm)")?;
    let reader = |pipe: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut text = String::new();
            if let Some(mut pipe) = pipe {
                let _ = pipe.read_to_string(&mut text);
            }
            text
        })
    };
    let stdout = reader(
        child
            .stdout
            .take()
            .map(|pipe| Box::new(pipe) as Box<dyn Read + Send>),
    );
    let stderr = reader(
        child
            .stderr
            .take()
            .map(|pipe| Box::new(pipe) as Box<dyn Read + Send>),
    );
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().context("waiting for qemu")? {
            break status;
        }
        if started.elapsed() > QEMU_TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            bail!(
                "qemu-system-arm did not finish within {} s: killed",
                QEMU_TIMEOUT.as_secs()
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let join = |handle: std::thread::JoinHandle<String>| handle.join().unwrap_or_default();
    Ok(QemuRun {
        status: status.code(),
        stdout: join(stdout),
        stderr: join(stderr),
    })
}

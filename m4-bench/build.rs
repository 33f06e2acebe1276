//! Build script: writes the mps2-an386 memory map and the golden vectors (computed here, on the
//! host, with independent f64 models) into OUT_DIR, and tells the linker to use cortex-m-rt's
//! link.x.

// Shared with the target, which uses the decoding half.
#[allow(dead_code)]
#[path = "src/format.rs"]
mod format;
#[path = "build/golden.rs"]
mod golden;
#[path = "build/hard_calibrations.rs"]
mod hard_calibrations;
#[path = "build/reference.rs"]
mod reference;

use std::error::Error;
use std::path::PathBuf;

/// QEMU's mps2-an386 (Cortex-M4 with FPU): 4 MiB code RAM at 0, 4 MiB RAM at 0x2000_0000.
/// Deliberately unlike the STM32F411's map (flash at 0x0800_0000), so that picking up the wrong
/// memory.x is visible in the ELF and refused by `cargo xtask m4-test`.
const MEMORY_X: &str = "/* mps2-an386, written by m4-bench/build.rs */
MEMORY
{
  FLASH : ORIGIN = 0x00000000, LENGTH = 4M
  RAM : ORIGIN = 0x20000000, LENGTH = 4M
}
";

fn main() -> Result<(), Box<dyn Error>> {
    // The linker looks for `INCLUDE memory.x` in its working directory (this crate's workspace
    // root) before the search path: a memory.x there would silently replace this one.
    let manifest_dir = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR")?);
    if manifest_dir.join("memory.x").exists() {
        return Err("m4-bench/memory.x would shadow the mps2-an386 map written to OUT_DIR".into());
    }
    let out_dir = PathBuf::from(std::env::var("OUT_DIR")?);
    std::fs::write(out_dir.join("memory.x"), MEMORY_X)?;
    println!("cargo:rustc-link-search={}", out_dir.display());
    println!("cargo:rustc-link-arg-bins=-Tlink.x");

    let points = model_core::ARTICLE_TABLE_1;
    let pressures_kpa: Vec<f64> = points.iter().map(|p| f64::from(p.pressure_kpa)).collect();
    let relative_changes: Vec<f64> = points
        .iter()
        .map(|p| f64::from(p.relative_change))
        .collect();
    let references = reference::References::new(&pressures_kpa, &relative_changes)
        .ok_or("the reference refused the article's calibration points")?;
    let calibrations = hard_calibrations::hard_calibrations()?;
    std::fs::write(
        out_dir.join("golden.bin"),
        golden::file(&references, &calibrations)?,
    )?;

    let opt_level = std::env::var("OPT_LEVEL").unwrap_or_default();
    println!("cargo:rustc-env=M4_BENCH_OPT_LEVEL={opt_level}");
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=build");
    println!("cargo:rerun-if-changed=src/format.rs");
    Ok(())
}

//! The firmware's footprint for the report: builds it with `cargo fw-build` (a no-op when it is
//! up to date), reads its sections, and the opt-level of the `firmware` profile from Cargo.toml.

use std::path::Path;

use anyhow::{anyhow, Context, Result};

use crate::elf::{self, Section};
use crate::m4;

/// Flash budget of the firmware image (vector table, code, constants, .data initialisers): the
/// multi-pad budget, since one firmware (1 to 8 pads, found at boot) ships for every board.
pub const FLASH_BUDGET_BYTES: u64 = 128 * 1024;
/// Static RAM budget (.data, .bss, .uninit; the stack comes on top), for state of 8 pads.
pub const STATIC_RAM_BUDGET_BYTES: u64 = 64 * 1024;

/// The profile `cargo fw-build` uses.
pub const PROFILE: &str = "firmware";

/// What the report says about the firmware.
#[derive(Debug, Clone, PartialEq)]
pub struct Footprint {
    /// The ELF, relative to the target directory.
    pub path: String,
    /// The `firmware` profile's opt-level as Cargo.toml gives it (`"z"`, `3`, ...).
    pub opt_level: String,
    /// model-core's opt-level in the `firmware` profile (its package override, if any).
    pub model_core_opt_level: String,
    /// Allocated sections.
    pub sections: Vec<Section>,
    /// Flash bytes (every read-only section and the initial values of `.data`).
    pub flash_bytes: u64,
    /// Static RAM bytes (`.data`, `.bss`, `.uninit`).
    pub ram_bytes: u64,
}

impl Footprint {
    /// Within both budgets.
    pub fn within_budget(&self) -> bool {
        self.flash_bytes <= FLASH_BUDGET_BYTES && self.ram_bytes <= STATIC_RAM_BUDGET_BYTES
    }
}

/// A setting of `[profile.<profile>]` in a Cargo.toml, following `inherits` (a profile without
/// one of its own inherits it), else cargo's default for the built-in profile at the root of
/// the chain (`release` and `bench`, or `dev` and `test`). Strings keep their quotes (`"z"`),
/// numbers and booleans are as written; `lto = true` reads as `"fat"`, which it means.
pub fn profile_setting(manifest: &str, profile: &str, key: &str) -> Result<String> {
    let document: toml::Table = manifest.parse().context("parsing Cargo.toml")?;
    let profiles = document.get("profile").and_then(toml::Value::as_table);
    let mut name = profile.to_string();
    for _ in 0..8 {
        let table = profiles
            .and_then(|profiles| profiles.get(&name))
            .and_then(toml::Value::as_table);
        if let Some(value) = table.and_then(|table| table.get(key)) {
            return Ok(match (key, value) {
                ("lto", toml::Value::Boolean(true)) => "\"fat\"".to_string(),
                (_, toml::Value::String(text)) => format!("\"{text}\""),
                (_, other) => other.to_string(),
            });
        }
        match table
            .and_then(|table| table.get("inherits"))
            .and_then(toml::Value::as_str)
        {
            Some(parent) => name = parent.to_string(),
            None => {
                let release = matches!(name.as_str(), "release" | "bench");
                let dev = matches!(name.as_str(), "dev" | "test");
                let default = match key {
                    "opt-level" if release => "3",
                    "opt-level" if dev => "0",
                    "lto" if release || dev => "false",
                    "codegen-units" if release => "16",
                    "codegen-units" if dev => "256",
                    _ => {
                        return Err(anyhow!(
                            "profile `{name}` has no {key}, no inherits and no known default"
                        ))
                    }
                };
                return Ok(default.to_string());
            }
        }
    }
    Err(anyhow!("profile `{profile}` inherits in a loop"))
}

/// The opt-level of `[profile.<profile>]` (see [`profile_setting`]).
pub fn profile_opt_level(manifest: &str, profile: &str) -> Result<String> {
    profile_setting(manifest, profile, "opt-level")
}

/// The settings that decide code generation, and so the instruction counts.
pub const CODE_GENERATION_KEYS: [&str; 3] = ["opt-level", "lto", "codegen-units"];

/// The package whose code generation the firmware may set apart from its own
/// (`[profile.firmware.package.model-core]`: the hot path built for speed inside a firmware
/// built for size), and so the counts depend on.
pub const MEASURED_PACKAGE: &str = "model-core";

/// The opt-level `[profile.<profile>.package.<package>]` gives, following `inherits` (the
/// nearest profile in the chain with an override wins), else the profile's own opt-level.
pub fn package_opt_level(manifest: &str, profile: &str, package: &str) -> Result<String> {
    let document: toml::Table = manifest.parse().context("parsing Cargo.toml")?;
    let profiles = document.get("profile").and_then(toml::Value::as_table);
    let mut name = profile.to_string();
    for _ in 0..8 {
        let table = profiles
            .and_then(|profiles| profiles.get(&name))
            .and_then(toml::Value::as_table);
        if let Some(value) = table
            .and_then(|table| table.get("package"))
            .and_then(toml::Value::as_table)
            .and_then(|packages| packages.get(package))
            .and_then(toml::Value::as_table)
            .and_then(|settings| settings.get("opt-level"))
        {
            return Ok(match value {
                toml::Value::String(text) => format!("\"{text}\""),
                other => other.to_string(),
            });
        }
        match table
            .and_then(|table| table.get("inherits"))
            .and_then(toml::Value::as_str)
        {
            Some(parent) => name = parent.to_string(),
            None => return profile_opt_level(manifest, profile),
        }
    }
    Err(anyhow!("profile `{profile}` inherits in a loop"))
}

/// `key = value` for each of [`CODE_GENERATION_KEYS`] of a profile, then the opt-level of
/// [`MEASURED_PACKAGE`] under it.
pub fn code_generation(manifest: &str, profile: &str) -> Result<Vec<(String, String)>> {
    let mut settings = CODE_GENERATION_KEYS
        .iter()
        .map(|key| Ok((key.to_string(), profile_setting(manifest, profile, key)?)))
        .collect::<Result<Vec<_>>>()?;
    settings.push((
        format!("{MEASURED_PACKAGE} opt-level"),
        package_opt_level(manifest, profile, MEASURED_PACKAGE)?,
    ));
    Ok(settings)
}

/// Builds the firmware (`cargo fw-build`) and reads its footprint.
pub fn build_and_measure(root: &Path) -> Result<Footprint> {
    println!("building the firmware (cargo fw-build; a no-op when it is up to date)");
    m4::run_checked(m4::cargo().current_dir(root).arg("fw-build"))?;
    let relative = format!("{}/{PROFILE}/firmware", m4::TARGET);
    let path = m4::target_directory(root, "Cargo.toml")?.join(&relative);
    let sections = elf::sections(&path).with_context(|| format!("reading {}", path.display()))?;
    let (flash_bytes, ram_bytes) = elf::flash_and_ram(&sections);
    let manifest =
        std::fs::read_to_string(root.join("Cargo.toml")).context("reading Cargo.toml")?;
    Ok(Footprint {
        path: relative,
        opt_level: profile_opt_level(&manifest, PROFILE)?,
        model_core_opt_level: package_opt_level(&manifest, PROFILE, MEASURED_PACKAGE)?,
        sections,
        flash_bytes,
        ram_bytes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_opt_level_is_read_through_inherits() {
        let manifest = r#"
[profile.release]
lto = "fat"

[profile.firmware]
inherits = "release"
opt-level = "z"

[profile.small]
inherits = "firmware"

[profile.fast]
inherits = "release"

[profile.numeric]
opt-level = 2
"#;
        assert_eq!(profile_opt_level(manifest, "firmware").unwrap(), "\"z\"");
        assert_eq!(profile_opt_level(manifest, "small").unwrap(), "\"z\"");
        assert_eq!(profile_opt_level(manifest, "fast").unwrap(), "3");
        assert_eq!(profile_opt_level(manifest, "numeric").unwrap(), "2");
        assert!(profile_opt_level(manifest, "missing").is_err());
        assert_eq!(
            code_generation(manifest, "small").unwrap(),
            vec![
                ("opt-level".to_string(), "\"z\"".to_string()),
                ("lto".to_string(), "\"fat\"".to_string()),
                ("codegen-units".to_string(), "16".to_string()),
                ("model-core opt-level".to_string(), "\"z\"".to_string()),
            ]
        );
        let with_override = format!(
            "{manifest}\n[profile.firmware.package.model-core]\nopt-level = 3\n\n\
             [profile.firmware.package.other]\nopt-level = 1\n"
        );
        assert_eq!(
            package_opt_level(&with_override, "firmware", "model-core").unwrap(),
            "3"
        );
        assert_eq!(
            package_opt_level(&with_override, "small", "model-core").unwrap(),
            "3"
        );
        assert_eq!(
            package_opt_level(&with_override, "fast", "model-core").unwrap(),
            "3"
        );
        assert_eq!(
            package_opt_level(&with_override, "numeric", "model-core").unwrap(),
            "2"
        );
        assert_eq!(profile_opt_level(&with_override, "small").unwrap(), "\"z\"");
        let with_bool = "[profile.release]\nlto = true\ncodegen-units = 1\n";
        assert_eq!(
            profile_setting(with_bool, "release", "lto").unwrap(),
            "\"fat\""
        );
        assert_eq!(
            profile_setting(with_bool, "release", "codegen-units").unwrap(),
            "1"
        );
        assert!(profile_setting(manifest, "numeric", "lto").is_err());
    }
}

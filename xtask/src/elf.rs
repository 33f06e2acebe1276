//! What the ELF files say: section addresses (to prove the right memory map was linked),
//! function symbols (for the instruction-mix trace) and flash/RAM use (for the firmware footprint).

use std::path::Path;

use anyhow::{bail, Context, Result};
use object::{Object, ObjectSection, ObjectSymbol, SectionFlags, SectionKind, SymbolKind};

/// QEMU mps2-an386: code RAM at 0 and RAM at 0x2000_0000, 4 MiB each.
pub const MPS2_CODE: (u64, u64) = (0x0000_0000, 4 << 20);
/// See [`MPS2_CODE`].
pub const MPS2_RAM: (u64, u64) = (0x2000_0000, 4 << 20);

/// An allocated section.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    /// Name (`.text`, `.bss`, ...).
    pub name: String,
    /// Run-time address.
    pub address: u64,
    /// Size in bytes.
    pub size: u64,
    /// Occupies no file space (`.bss`, `.uninit`).
    pub no_bits: bool,
    /// Writable at run time.
    pub writable: bool,
}

/// A function symbol.
#[derive(Debug, Clone, PartialEq)]
pub struct Function {
    /// Mangled name.
    pub name: String,
    /// Start address (Thumb bit cleared).
    pub address: u64,
    /// Size in bytes.
    pub size: u64,
}

/// The allocated (loaded) sections of an ELF.
pub fn sections(path: &Path) -> Result<Vec<Section>> {
    let data = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let file =
        object::File::parse(&*data).with_context(|| format!("parsing {}", path.display()))?;
    let mut sections = Vec::new();
    for section in file.sections() {
        let SectionFlags::Elf { sh_flags } = section.flags() else {
            continue;
        };
        const SHF_WRITE: u64 = 0x1;
        const SHF_ALLOC: u64 = 0x2;
        if sh_flags & SHF_ALLOC == 0 || section.size() == 0 {
            continue;
        }
        sections.push(Section {
            name: section.name().unwrap_or("?").to_string(),
            address: section.address(),
            size: section.size(),
            no_bits: section.kind() == SectionKind::UninitializedData,
            writable: sh_flags & SHF_WRITE != 0,
        });
    }
    Ok(sections)
}

fn within(section: &Section, (start, length): (u64, u64)) -> bool {
    section.address >= start && section.address + section.size <= start + length
}

/// Refuses an ELF not linked for mps2-an386: the vector table must sit at 0, code and constants
/// in the code RAM, writable data in the RAM. This is what catches a wrong `memory.x` (the
/// STM32's puts flash at 0x0800_0000).
pub fn check_mps2_layout(sections: &[Section]) -> Result<()> {
    let vector_table = sections
        .iter()
        .find(|section| section.name == ".vector_table");
    match vector_table {
        Some(section) if section.address == MPS2_CODE.0 => {}
        Some(section) => bail!(
            ".vector_table is at {:#010x}, not 0: the ELF was linked with another memory.x",
            section.address
        ),
        None => bail!("the ELF has no .vector_table"),
    }
    for section in sections {
        let region = if section.writable {
            MPS2_RAM
        } else {
            MPS2_CODE
        };
        if !within(section, region) {
            bail!(
                "{} at {:#010x}..{:#010x} is outside the mps2-an386 {} region: wrong memory.x",
                section.name,
                section.address,
                section.address + section.size,
                if section.writable { "RAM" } else { "code" }
            );
        }
    }
    Ok(())
}

/// Flash and RAM use of a firmware ELF: (flash bytes, static RAM bytes). Flash holds every
/// read-only section and the initial values of `.data`; RAM holds `.data`, `.bss` and
/// `.uninit` (the stack comes on top).
pub fn flash_and_ram(sections: &[Section]) -> (u64, u64) {
    let mut flash = 0;
    let mut ram = 0;
    for section in sections {
        if section.writable {
            ram += section.size;
            if !section.no_bits {
                flash += section.size;
            }
        } else {
            flash += section.size;
        }
    }
    (flash, ram)
}

/// The function symbols of an ELF.
pub fn functions(path: &Path) -> Result<Vec<Function>> {
    let data = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let file =
        object::File::parse(&*data).with_context(|| format!("parsing {}", path.display()))?;
    Ok(file
        .symbols()
        .filter(|symbol| symbol.kind() == SymbolKind::Text && symbol.size() > 0)
        .filter_map(|symbol| {
            Some(Function {
                name: symbol.name().ok()?.to_string(),
                address: symbol.address() & !1,
                size: symbol.size(),
            })
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn section(name: &str, address: u64, size: u64, writable: bool, no_bits: bool) -> Section {
        Section {
            name: name.to_string(),
            address,
            size,
            no_bits,
            writable,
        }
    }

    #[test]
    fn the_mps2_layout_passes_and_the_stm32_layout_is_refused() {
        let mps2 = [
            section(".vector_table", 0, 0x400, false, false),
            section(".text", 0x400, 0x1_0000, false, false),
            section(".bss", 0x2000_0000, 12, true, true),
        ];
        assert!(check_mps2_layout(&mps2).is_ok());
        let stm32 = [
            section(".vector_table", 0x0800_0000, 0x400, false, false),
            section(".text", 0x0800_0400, 0x1_0000, false, false),
        ];
        let message = check_mps2_layout(&stm32).unwrap_err().to_string();
        assert!(message.contains("memory.x"), "{message}");
        let data_in_code = [
            section(".vector_table", 0, 0x400, false, false),
            section(".data", 0x400, 16, true, false),
        ];
        assert!(check_mps2_layout(&data_in_code).is_err());
    }

    #[test]
    fn flash_counts_data_initialisers_and_ram_counts_bss() {
        let sections = [
            section(".vector_table", 0x0800_0000, 0x400, false, false),
            section(".text", 0x0800_0400, 1000, false, false),
            section(".data", 0x2000_0000, 40, true, false),
            section(".bss", 0x2000_0028, 100, true, true),
        ];
        assert_eq!(flash_and_ram(&sections), (0x400 + 1000 + 40, 140));
    }
}

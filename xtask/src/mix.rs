//! The dynamic instruction mix of each tier's conversion, from a QEMU trace, and the cycle
//! estimate built on it.
//!
//! The `instruction-mix` build of m4-bench runs each tier's conversion loop once over its single
//! inputs, then the same loop without the conversion; then each tier's temperature-corrected
//! inversion (dC/C0 and the inverse called directly) and its empty loop; then dC/C0 alone and
//! the empty loop. QEMU logs (`-d in_asm,exec,nochain`) every translated block and every block
//! executed, restricted by `-dfilter` to those loops and the functions they call (found by
//! following branch targets until no new function appears). The blocks executed between two loop
//! entries, classified instruction by instruction, minus the empty loop's, divided by the inputs,
//! give the mix per call.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};
use model_core::Tier;

use crate::elf::Function;
use crate::m4;

/// Counts per instruction class (per conversion once divided).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Mix {
    /// Every instruction (condition-failed ones in IT blocks included, as the core issues them).
    pub instructions: f64,
    /// VDIV and VSQRT: 14 cycles each.
    pub fp_divide: f64,
    /// SDIV and UDIV: 2 to 12 cycles.
    pub integer_divide: f64,
    /// VMLA, VMLS, VNMLA, VNMLS, VFMA, VFMS, VFNMA, VFNMS: 3 cycles.
    pub fp_multiply_accumulate: f64,
    /// Other FP arithmetic (VADD, VSUB, VMUL, VNMUL, VCVT, VABS, VNEG): 1 cycle, +1 when the
    /// next instruction uses the result.
    pub fp_arithmetic: f64,
    /// LDR* and VLDR: 2 cycles, 1 when pipelined behind another load or store.
    pub single_loads: f64,
    /// VSTR: 2 cycles.
    pub fp_stores: f64,
    /// Words moved by LDM, STM, PUSH, POP, VLDM, VSTM, VPUSH, VPOP, LDRD, STRD: 1 + N cycles.
    pub multiple_words: f64,
    /// B, BL, BX, BLX, TBB, TBH, POP/LDM of PC: always taken, 1 + P cycles (P = 1 to 3).
    pub unconditional_branches: f64,
    /// B<cond>, BX<cond>, CBZ, CBNZ: 1 cycle if not taken, 1 + P if taken.
    pub conditional_branches: f64,
}

impl Mix {
    fn add(&mut self, other: &Mix, sign: f64) {
        self.instructions += sign * other.instructions;
        self.fp_divide += sign * other.fp_divide;
        self.integer_divide += sign * other.integer_divide;
        self.fp_multiply_accumulate += sign * other.fp_multiply_accumulate;
        self.fp_arithmetic += sign * other.fp_arithmetic;
        self.single_loads += sign * other.single_loads;
        self.fp_stores += sign * other.fp_stores;
        self.multiple_words += sign * other.multiple_words;
        self.unconditional_branches += sign * other.unconditional_branches;
        self.conditional_branches += sign * other.conditional_branches;
    }

    fn scaled(mut self, factor: f64) -> Mix {
        let copy = self;
        self = Mix::default();
        self.add(&copy, factor);
        self
    }

    /// Cycles assuming the best case the Cortex-M4 timing tables allow: loads pipelined, no
    /// dependent-use stalls, branch refill P = 1, conditional branches not taken, 2-cycle
    /// integer division. No flash wait states.
    pub fn cycles_lower(&self) -> f64 {
        self.instructions
            + 13.0 * self.fp_divide
            + self.integer_divide
            + 2.0 * self.fp_multiply_accumulate
            + self.fp_stores
            + self.multiple_words
            + self.unconditional_branches
    }

    /// Cycles assuming the worst case: no load pipelining, every FP result used at once, every
    /// branch taken with P = 3, 12-cycle division. No flash wait states.
    pub fn cycles_upper(&self) -> f64 {
        self.cycles_lower()
            + self.single_loads
            + self.fp_arithmetic
            + 2.0 * self.unconditional_branches
            + 3.0 * self.conditional_branches
            + 10.0 * self.integer_divide
    }

    /// Classifies one instruction (mnemonic and operands as QEMU's disassembler prints them).
    pub fn count(&mut self, mnemonic: &str, operands: &str) {
        self.instructions += 1.0;
        let (base, conditional) = base_mnemonic(mnemonic);
        let words = register_words(operands);
        let writes_pc = operands.contains("pc}");
        match base.as_str() {
            "vdiv" | "vsqrt" => self.fp_divide += 1.0,
            "sdiv" | "udiv" => self.integer_divide += 1.0,
            "vmla" | "vmls" | "vnmla" | "vnmls" | "vfma" | "vfms" | "vfnma" | "vfnms" => {
                self.fp_multiply_accumulate += 1.0
            }
            "vadd" | "vsub" | "vmul" | "vnmul" | "vcvt" | "vcvtr" | "vabs" | "vneg" => {
                self.fp_arithmetic += 1.0
            }
            "vldr" => self.single_loads += 1.0,
            "vstr" => self.fp_stores += 1.0,
            "ldrd" | "strd" => self.multiple_words += 2.0,
            "ldm" | "ldmia" | "ldmdb" | "ldmfd" | "pop" | "stm" | "stmia" | "stmdb" | "stmfd"
            | "push" | "vldm" | "vldmia" | "vldmdb" | "vstm" | "vstmia" | "vstmdb" | "vpush"
            | "vpop" => {
                self.multiple_words += words;
                if writes_pc {
                    self.unconditional_branches += 1.0;
                }
            }
            "b" | "bl" | "blx" | "bx" | "tbb" | "tbh" => {
                if conditional {
                    self.conditional_branches += 1.0;
                } else {
                    self.unconditional_branches += 1.0;
                }
            }
            "cbz" | "cbnz" => self.conditional_branches += 1.0,
            other if other.starts_with("ldr") => {
                self.single_loads += 1.0;
                if operands.starts_with("pc,") {
                    self.unconditional_branches += 1.0;
                }
            }
            _ => {}
        }
    }
}

const CONDITIONS: [&str; 16] = [
    "eq", "ne", "cs", "hs", "cc", "lo", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le",
];

const KNOWN: [&str; 40] = [
    "vdiv", "vsqrt", "sdiv", "udiv", "vmla", "vmls", "vnmla", "vnmls", "vfma", "vfms", "vfnma",
    "vfnms", "vadd", "vsub", "vmul", "vnmul", "vcvt", "vcvtr", "vabs", "vneg", "vldr", "vstr",
    "ldrd", "strd", "ldm", "pop", "stm", "push", "vldm", "vstm", "vpush", "vpop", "b", "bl", "blx",
    "bx", "tbb", "tbh", "cbz", "cbnz",
];

/// The mnemonic without size qualifiers (`.w`, `.f32`) and condition suffix, and whether it had
/// a condition.
fn base_mnemonic(mnemonic: &str) -> (String, bool) {
    let lower = mnemonic.to_ascii_lowercase();
    let stem = lower.split('.').next().unwrap_or("").to_string();
    if KNOWN.contains(&stem.as_str()) || stem.starts_with("ldr") && stem.len() <= 5 {
        return (stem, false);
    }
    for condition in CONDITIONS {
        if let Some(base) = stem.strip_suffix(condition) {
            if KNOWN.contains(&base) || base.starts_with("ldr") || base.starts_with("mov") {
                return (base.to_string(), true);
            }
        }
    }
    (stem, false)
}

/// Words in a register list (`{r4, r5, lr}` = 3, `{d8, d9}` = 4), 0 without one.
fn register_words(operands: &str) -> f64 {
    let (Some(open), Some(close)) = (operands.find('{'), operands.find('}')) else {
        return 0.0;
    };
    operands[open + 1..close]
        .split(',')
        .map(str::trim)
        .filter(|register| !register.is_empty())
        .map(|register| if register.starts_with('d') { 2.0 } else { 1.0 })
        .sum()
}

/// One disassembled instruction.
#[derive(Debug, Clone, PartialEq)]
struct Instruction {
    mnemonic: String,
    operands: String,
}

/// A parsed QEMU log: translated blocks by start address, executed block starts in order.
#[derive(Debug, Default)]
struct Trace {
    blocks: BTreeMap<u64, Vec<Instruction>>,
    executed: Vec<u64>,
}

fn hex(text: &str) -> Option<u64> {
    u64::from_str_radix(text.trim().trim_start_matches("0x"), 16).ok()
}

/// `0x000080c8:  f85a 1b04  ldr      r1, [sl], #4` -> (address, instruction).
fn parse_instruction(line: &str) -> Option<(u64, Instruction)> {
    let (address, rest) = line.split_once(':')?;
    let address = hex(address)?;
    let mut tokens = rest.split_whitespace().peekable();
    for _ in 0..2 {
        match tokens.peek() {
            Some(token) if token.len() == 4 && token.chars().all(|c| c.is_ascii_hexdigit()) => {
                tokens.next();
            }
            _ => break,
        }
    }
    let mnemonic = tokens.next()?.to_string();
    let operands = tokens.collect::<Vec<_>>().join(" ");
    Some((address, Instruction { mnemonic, operands }))
}

fn parse_trace(path: &Path) -> Result<Trace> {
    let file = std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
    let mut trace = Trace::default();
    let mut current: Option<(u64, Vec<Instruction>)> = None;
    for line in BufReader::new(file).lines() {
        let line = line?;
        if line.starts_with("0x") {
            if let Some((address, instruction)) = parse_instruction(&line) {
                match current.as_mut() {
                    Some((_, instructions)) => instructions.push(instruction),
                    None => current = Some((address, vec![instruction])),
                }
            }
            continue;
        }
        if let Some((start, instructions)) = current.take() {
            trace.blocks.insert(start, instructions);
        }
        if line.starts_with("Trace ") {
            let pc = line
                .split_once('[')
                .and_then(|(_, rest)| rest.split('/').nth(1))
                .and_then(hex)
                .ok_or_else(|| anyhow!("unexpected trace line: {line}"))?;
            trace.executed.push(pc);
        }
    }
    if let Some((start, instructions)) = current.take() {
        trace.blocks.insert(start, instructions);
    }
    Ok(trace)
}

/// Direct branch and call targets of the traced blocks.
fn branch_targets(trace: &Trace) -> Vec<u64> {
    let mut targets = Vec::new();
    for instruction in trace.blocks.values().flatten() {
        let (base, _) = base_mnemonic(&instruction.mnemonic);
        if matches!(base.as_str(), "b" | "bl" | "blx" | "cbz" | "cbnz") {
            if let Some(target) = instruction.operands.rsplit('#').next().and_then(hex) {
                targets.push(target);
            }
        }
    }
    targets
}

/// The instruction mix per conversion of every tier, and the functions that were traced.
#[derive(Debug, Clone)]
pub struct MixReport {
    /// Per tier, per `TaxelModel::convert`.
    pub per_tier: Vec<(Tier, Mix)>,
    /// Per tier, per temperature-corrected inversion (dC/C0, then the inverse called directly).
    pub corrected: Vec<(Tier, Mix)>,
    /// Per `Baseline::relative_change` (dC/C0 alone).
    pub relative_change: Mix,
    /// Inputs each tier converted.
    pub inputs_per_tier: u32,
    /// Inputs of each corrected inversion (the capacitance readings among them).
    pub corrected_inputs: u32,
    /// Functions inside the address filter.
    pub traced_functions: Vec<String>,
}

/// What a traced loop is, from the function whose entry starts it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LoopKind {
    Convert,
    ConvertEmpty,
    Corrected,
    CorrectedEmpty,
    RelativeChange,
}

/// The loop entries of the probe, in the order it runs them: per tier the conversion and its
/// empty loop, per tier the corrected inversion and its empty loop, then dC/C0 and the empty loop.
fn expected_loops() -> Vec<LoopKind> {
    let mut expected = Vec::new();
    for _ in Tier::ALL {
        expected.extend([LoopKind::Convert, LoopKind::ConvertEmpty]);
    }
    for _ in Tier::ALL {
        expected.extend([LoopKind::Corrected, LoopKind::CorrectedEmpty]);
    }
    expected.extend([LoopKind::RelativeChange, LoopKind::CorrectedEmpty]);
    expected
}

/// Work minus empty loop, per input, for consecutive (work, empty) segments.
fn per_call(segments: &[(LoopKind, Mix)], inputs: u32) -> Vec<Mix> {
    segments
        .chunks(2)
        .filter_map(|pair| match pair {
            [(_, work), (_, empty)] => {
                let mut difference = *work;
                difference.add(empty, -1.0);
                Some(difference.scaled(1.0 / f64::from(inputs.max(1))))
            }
            _ => None,
        })
        .collect()
}

/// A legacy-mangled Rust name (`_ZN8m4_bench8counting12convert_loop17h...E`) as a path without
/// its hash (`m4_bench::counting::convert_loop`); other names unchanged.
pub fn demangle(name: &str) -> String {
    let Some(mut rest) = name
        .strip_prefix("_ZN")
        .and_then(|rest| rest.strip_suffix('E'))
    else {
        return name.to_string();
    };
    let mut segments = Vec::new();
    while !rest.is_empty() {
        let digits = rest.chars().take_while(char::is_ascii_digit).count();
        let Ok(length) = rest[..digits].parse::<usize>() else {
            return name.to_string();
        };
        let Some(segment) = rest.get(digits..digits + length) else {
            return name.to_string();
        };
        segments.push(segment);
        rest = &rest[digits + length..];
    }
    if segments
        .last()
        .is_some_and(|last| last.len() == 17 && last.starts_with('h'))
    {
        segments.pop();
    }
    segments.join("::")
}

/// Every function whose (mangled) name contains `fragment`; at least one.
fn find_all(functions: &[Function], fragment: &str) -> Result<Vec<Function>> {
    let found: Vec<Function> = functions
        .iter()
        .filter(|function| function.name.contains(fragment))
        .cloned()
        .collect();
    if found.is_empty() {
        bail!("no function named like `{fragment}` in the instruction-mix ELF");
    }
    Ok(found)
}

/// Traces the instruction-mix build of m4-bench. `log_path` is a scratch file.
pub fn trace(elf: &Path, log_path: &Path) -> Result<MixReport> {
    let functions = crate::elf::functions(elf)?;
    let mut entries: Vec<(u64, LoopKind)> = Vec::new();
    let mut filtered: Vec<Function> = Vec::new();
    for (fragment, kind) in [
        ("8counting12convert_loop17h", LoopKind::Convert),
        (
            "8counting21convert_overhead_loop17h",
            LoopKind::ConvertEmpty,
        ),
        (
            "8counting24corrected_inversion_loop17h",
            LoopKind::Corrected,
        ),
        (
            "8counting33corrected_inversion_overhead_loop17h",
            LoopKind::CorrectedEmpty,
        ),
        (
            "8counting20relative_change_loop17h",
            LoopKind::RelativeChange,
        ),
    ] {
        for function in find_all(&functions, fragment)? {
            entries.push((function.address, kind));
            filtered.push(function);
        }
    }
    let mut inputs_per_tier = 0;
    let mut corrected_inputs = 0;
    let mut trace = Trace::default();
    for _round in 0..8 {
        let ranges: Vec<String> = filtered
            .iter()
            .map(|function| format!("{:#x}+{:#x}", function.address, function.size))
            .collect();
        let _ = std::fs::remove_file(log_path);
        let mut command = m4::qemu_command(elf, false);
        command
            .args([
                "-d",
                "in_asm,exec,nochain",
                "-dfilter",
                &ranges.join(","),
                "-D",
            ])
            .arg(log_path);
        let run = m4::run_qemu(command)?;
        let line = run
            .stdout
            .lines()
            .find(|line| line.starts_with("mix "))
            .and_then(crate::bench_output::Line::parse);
        if run.status != Some(0) || line.is_none() {
            bail!(
                "the instruction-mix run failed ({:?}):\n{}{}",
                run.status,
                run.stdout,
                run.stderr
            );
        }
        if let Some(line) = line {
            inputs_per_tier = line.number("inputs_per_tier")? as u32;
            corrected_inputs = line.number("corrected_inputs")? as u32;
        }
        trace = parse_trace(log_path)?;
        let mut added = false;
        for target in branch_targets(&trace) {
            let inside = |function: &Function| {
                target >= function.address && target < function.address + function.size
            };
            if filtered.iter().any(inside) {
                continue;
            }
            if let Some(function) = functions.iter().find(|function| inside(function)) {
                filtered.push(function.clone());
                added = true;
            }
        }
        if !added {
            break;
        }
    }
    let _ = std::fs::remove_file(log_path);

    let mut segments: Vec<(LoopKind, Mix)> = Vec::new();
    for pc in &trace.executed {
        if let Some((_, kind)) = entries.iter().find(|(address, _)| address == pc) {
            segments.push((*kind, Mix::default()));
        }
        let (Some((_, mix)), Some(block)) = (segments.last_mut(), trace.blocks.get(pc)) else {
            continue;
        };
        for instruction in block {
            mix.count(&instruction.mnemonic, &instruction.operands);
        }
    }
    let kinds: Vec<LoopKind> = segments.iter().map(|(kind, _)| *kind).collect();
    if kinds != expected_loops() || inputs_per_tier == 0 || corrected_inputs == 0 {
        bail!(
            "the trace's loop runs are not the probe's (expected a work and an empty loop per \
             tier for the conversion, then for the corrected inversion, then dC/C0): {kinds:?}"
        );
    }
    let tiers = Tier::ALL.len();
    let convert = per_call(&segments[..2 * tiers], inputs_per_tier);
    let corrected = per_call(&segments[2 * tiers..4 * tiers], corrected_inputs);
    let relative_change = per_call(&segments[4 * tiers..], corrected_inputs);
    Ok(MixReport {
        per_tier: Tier::ALL.into_iter().zip(convert).collect(),
        corrected: Tier::ALL.into_iter().zip(corrected).collect(),
        relative_change: relative_change.first().copied().unwrap_or_default(),
        inputs_per_tier,
        corrected_inputs,
        traced_functions: filtered
            .into_iter()
            .map(|function| demangle(&function.name))
            .fold(Vec::new(), |mut names, name| {
                if !names.contains(&name) {
                    names.push(name);
                }
                names
            }),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mnemonics_are_classified_with_conditions_and_qualifiers() {
        let mut mix = Mix::default();
        for (mnemonic, operands) in [
            ("vdiv.f32", "s0, s1, s2"),
            ("vmla.f32", "s0, s4, s2"),
            ("vmovmi.f32", "s0, s18"),
            ("ldr", "r1, [sl], #4"),
            ("ldrb.w", "r1, [sp, #0x1c]"),
            ("vldr", "s2, [r0, #0x208]"),
            ("push.w", "{r8, sb, sl, fp}"),
            ("vpush", "{d8, d9}"),
            ("pop", "{r4, r5, r6, r7, pc}"),
            ("bxeq", "lr"),
            ("b", "#0x80c6"),
            ("beq.w", "#0x8480"),
            ("bl", "#0x12a60"),
            ("cbz", "r0, #0x8100"),
            ("movhs", "r1, #0x40"),
            ("vmul.f32", "s0, s0, s2"),
        ] {
            mix.count(mnemonic, operands);
        }
        assert_eq!(mix.instructions, 16.0);
        assert_eq!(mix.fp_divide, 1.0);
        assert_eq!(mix.fp_multiply_accumulate, 1.0);
        assert_eq!(mix.single_loads, 3.0);
        assert_eq!(mix.multiple_words, 4.0 + 4.0 + 5.0);
        assert_eq!(mix.unconditional_branches, 3.0);
        assert_eq!(mix.conditional_branches, 3.0);
        assert_eq!(mix.fp_arithmetic, 1.0);
        assert!(mix.cycles_upper() > mix.cycles_lower());
        assert_eq!(mix.cycles_lower(), 16.0 + 13.0 + 2.0 + 13.0 + 3.0);
    }

    #[test]
    fn qemu_log_lines_are_parsed() {
        let (address, instruction) =
            parse_instruction("0x00008092:  e92d 0f00  push.w   {r8, sb, sl, fp}").unwrap();
        assert_eq!(address, 0x8092);
        assert_eq!(instruction.mnemonic, "push.w");
        assert_eq!(instruction.operands, "{r8, sb, sl, fp}");
        let (_, short) = parse_instruction("0x0000808c:  4770       bxeq     lr").unwrap();
        assert_eq!(
            (short.mnemonic.as_str(), short.operands.as_str()),
            ("bxeq", "lr")
        );
        assert_eq!(register_words("{d8, d9, d10}"), 6.0);
        assert_eq!(base_mnemonic("addeq").0, "addeq");
        let mut conditional_load = Mix::default();
        conditional_load.count("ldrne", "r0, [r1]");
        assert_eq!(conditional_load.single_loads, 1.0);
        assert_eq!(base_mnemonic("bls"), ("b".to_string(), true));
        assert_eq!(base_mnemonic("bl"), ("bl".to_string(), false));
        assert_eq!(
            demangle("_ZN8m4_bench8counting12convert_loop17h3abd5e99b16654a3E"),
            "m4_bench::counting::convert_loop"
        );
        assert_eq!(demangle("fminf"), "fminf");
    }

    #[test]
    fn a_log_is_split_into_blocks_and_executions() {
        let directory = std::env::temp_dir().join(format!("xtask-mix-{}", std::process::id()));
        std::fs::create_dir_all(&directory).unwrap();
        let path = directory.join("trace.log");
        std::fs::write(
            &path,
            "----------------\nIN: f\n0x00008088:  2a00       cmp      r2, #0\n0x0000808a:  bf08       it       eq\n0x0000808c:  4770       bxeq     lr\n\nTrace 0: 0x7fdf8415b980 [00800400/00008088/00000010/ff020200] f\nTrace 0: 0x7fdf8415b980 [00800400/00008088/00000010/ff020200] f\n",
        )
        .unwrap();
        let trace = parse_trace(&path).unwrap();
        std::fs::remove_dir_all(&directory).unwrap();
        assert_eq!(trace.blocks[&0x8088].len(), 3);
        assert_eq!(trace.executed, vec![0x8088, 0x8088]);
    }
}

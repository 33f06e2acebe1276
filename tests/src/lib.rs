//! Cross-crate tests live in `tests/`; this library holds the fault-injection harness they share
//! with the reliability report (`cargo run --release -p taxel-tests --bin reliability`).

pub mod pad_faults;
pub mod reliability;
pub mod soak;

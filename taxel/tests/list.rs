//! `taxel list` as a user runs it: one line per attached board, or a plain "no board attached".

// Test helpers may unwrap: a failure is the test failing.
#![allow(clippy::unwrap_used)]

use std::process::Command;

#[test]
fn list_names_the_attached_boards_or_says_there_are_none() {
    let output = Command::new(env!("CARGO_BIN_EXE_taxel"))
        .arg("list")
        .output()
        .unwrap();
    assert!(output.status.success(), "{output:?}");
    let text = String::from_utf8(output.stdout).unwrap();
    let plausible = text == "no board attached\n"
        || text
            .lines()
            .all(|line| line.contains("1209:0001") && line.contains("serial"));
    assert!(plausible, "{text}");
}

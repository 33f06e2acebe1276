//! Every subcommand's help has a runnable example, and the lists in the help are complete.
#![allow(clippy::unwrap_used)]

mod support;

use std::process::Command;

use support::taxel_binary;

fn help(arguments: &[&str]) -> String {
    let output = Command::new(taxel_binary())
        .args(arguments)
        .arg("--help")
        .output()
        .unwrap();
    assert!(output.status.success(), "{arguments:?}");
    String::from_utf8(output.stdout).unwrap()
}

#[test]
fn every_subcommand_has_an_example() {
    for subcommand in [
        "demo",
        "sim",
        "convert",
        "calibrate",
        "calibration",
        "plot",
        "list",
        "record",
        "view",
    ] {
        let text = help(&[subcommand]);
        assert!(
            text.contains("Example") && text.contains(&format!("taxel {subcommand}")),
            "{subcommand}: {text}"
        );
    }
}

#[test]
fn the_tier_option_lists_every_tier() {
    let text = help(&["convert"]);
    for tier in model_core::Tier::ALL {
        assert!(
            text.contains(tier.name()),
            "{} missing: {text}",
            tier.name()
        );
    }
}

#[test]
fn the_demo_help_names_its_keys() {
    let text = help(&["demo"]);
    for key in ["t = tare", "p = pause", "q = quit"] {
        assert!(text.contains(key), "{key}: {text}");
    }
}

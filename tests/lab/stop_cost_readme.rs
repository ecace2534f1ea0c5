//! The README's table of what a stop costs per table profile (section *Instruments of
//! other makes*) is what `cargo run --release --example stop_cost` prints: the example's
//! code, run here, and the README's table compared line by line (tests/sweeps/readme.rs
//! leaves out blocks that run cargo).

#![cfg(feature = "lab")]

#[allow(dead_code)]
#[path = "../../examples/stop_cost.rs"]
mod stop_cost;

#[test]
fn the_readme_shows_what_the_stop_cost_example_prints() {
    let printed = stop_cost::table().unwrap();
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
    let block = readme
        .split("cargo run --release --example stop_cost\n```\n<!-- output of the block above -->\n```text\n")
        .nth(1)
        .and_then(|rest| rest.split("\n```").next())
        .expect("the README shows the example's output");
    let lines = |t: &str| {
        t.lines()
            .map(str::trim_end)
            .map(String::from)
            .collect::<Vec<_>>()
    };
    assert_eq!(lines(block), lines(&printed));
}

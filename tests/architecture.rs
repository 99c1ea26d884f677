//! The house's shape (issues 22 and 37, docs/design.md): no circle of imports between the
//! files of either crate's `src/` or between its top-level modules (test modules left out),
//! no source file over 1,000 lines without its tests, and a `hexcue-core` that depends on no
//! crate for files' formats, sockets, the terminal or Foxglove. `scripts/import-graph.py`
//! reads the code's own `use` paths; `cargo tree` lists hexcue-core's dependencies.

use std::process::Command;

fn import_graph(src: &str) {
    let root = env!("CARGO_MANIFEST_DIR");
    let out = match Command::new("python3")
        .arg(format!("{root}/scripts/import-graph.py"))
        .arg(format!("{root}/{src}"))
        .output()
    {
        Ok(out) => out,
        Err(e) => panic!("python3 is needed for this check (scripts/import-graph.py): {e}"),
    };
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{src}: the house has circles or oversized files:\n{report}{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn no_import_circles_and_no_oversized_files() {
    import_graph("src");
    import_graph("hexcue-core/src");
}

/// What a lab embedding the algorithms must not be made to build: MCAP, the terminal, async
/// runtimes, Foxglove, sockets and serial ports, compression, plotting.
const NOT_IN_THE_CORE: &[&str] = &[
    "mcap",
    "ratatui",
    "crossterm",
    "tokio",
    "foxglove",
    "tungstenite",
    "mio",
    "socket2",
    "serialport",
    "signal-hook",
    "libc",
    "zstd",
    "plotters",
    "csv",
    "indicatif",
];

#[test]
fn hexcue_core_depends_on_no_io_crate() {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "tree",
            "--offline",
            "-p",
            "hexcue-core",
            "-e",
            "normal",
            "--prefix",
            "none",
            "--format",
            "{p}",
        ])
        .output()
        .expect("cargo runs");
    assert!(
        out.status.success(),
        "cargo tree: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let tree = String::from_utf8_lossy(&out.stdout);
    let crates: Vec<&str> = tree
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .collect();
    assert!(
        crates.contains(&"hexcue-core") && crates.contains(&"nalgebra"),
        "{tree}"
    );
    let found: Vec<&&str> = NOT_IN_THE_CORE
        .iter()
        .filter(|c| crates.contains(c))
        .collect();
    assert!(
        found.is_empty(),
        "hexcue-core depends on {found:?}:\n{tree}"
    );
}

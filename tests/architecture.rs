//! The house's shape (issue 22, docs/design.md): no circle of imports between the files of
//! `src/` or between its top-level modules (test modules left out), and no source file over
//! 1,000 lines without its tests. `scripts/import-graph.py` reads the code's own `use` paths;
//! this test fails with its report, so a change that closes a circle is seen in CI.

use std::process::Command;

#[test]
fn no_import_circles_and_no_oversized_files() {
    let root = env!("CARGO_MANIFEST_DIR");
    let out = match Command::new("python3")
        .arg(format!("{root}/scripts/import-graph.py"))
        .arg(format!("{root}/src"))
        .output()
    {
        Ok(out) => out,
        Err(e) => panic!("python3 is needed for this check (scripts/import-graph.py): {e}"),
    };
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "the house has circles or oversized files:\n{report}{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

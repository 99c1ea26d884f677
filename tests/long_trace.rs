//! Long traces (issue 38, item 2): `play` streams a trace of any size, with no cap on the
//! file; `compare` and `tune`, which hold their traces in memory, refuse one beyond their
//! limit with a message that names the option that raises it (`--max-trace-mb`). The limit
//! is lowered here through that option, so that the test needs a few MB rather than 340.

mod common;

use std::io::Write;
use std::path::Path;

use common::*;

/// A smooth synthetic trace of `rows` rows at 100 Hz, as docs/make-long-trace.py writes it.
fn write_trace(path: &Path, rows: usize) {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    write!(out, "{}", common::trace_header(true)).unwrap();
    for k in 0..rows {
        let t = k as f64 / 100.0;
        writeln!(
            out,
            "{t:.2},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6}",
            1.5 * (0.3 * t).sin(),
            0.8 * (0.7 * t + 1.0).sin(),
            -9.80665 + 0.5 * (1.1 * t).sin(),
            0.05 * (0.9 * t).sin(),
            0.03 * (0.4 * t).sin(),
            0.02 * (0.2 * t).sin(),
            0.1 * (0.05 * t).sin(),
            0.05 * (0.03 * t).sin(),
            (0.01 * t) % std::f64::consts::TAU,
        )
        .unwrap();
    }
}

/// `compare` on the traces in `dir` with `--max-trace-mb` at `limit` bytes.
fn compare_with_limit(limit: u64, dir: &Path, md: &Path) -> std::process::Output {
    let mb = format!("{}", limit as f64 / 1e6);
    hexcue(&[
        "compare".as_ref(),
        "--algorithms".as_ref(),
        "cwf".as_ref(),
        "--traces".as_ref(),
        dir.as_os_str(),
        "--out".as_ref(),
        md.as_os_str(),
        "--force".as_ref(),
        "--max-trace-mb".as_ref(),
        mb.as_ref(),
    ])
}

#[test]
fn play_streams_a_trace_beyond_the_in_memory_limit_and_compare_says_how_to_raise_it() {
    let dir = tempfile::tempdir().unwrap();
    let traces = dir.path().join("traces");
    std::fs::create_dir(&traces).unwrap();
    let trace = traces.join("long.csv");
    let rows = 30_000;
    write_trace(&trace, rows);
    let size = std::fs::metadata(&trace).unwrap().len();
    let limit = size / 4;

    // Held in memory: refused, naming the file, the limit and the option that raises it.
    let md = dir.path().join("report.md");
    let out = compare_with_limit(limit, &traces, &md);
    let err = stderr(&out);
    assert!(
        !out.status.success(),
        "compare read a trace beyond its limit"
    );
    assert!(
        err.contains("long.csv")
            && err.contains(&format!("larger than {limit} bytes"))
            && err.contains("--max-trace-mb"),
        "{err}"
    );
    // Raised, it reads.
    let out = compare_with_limit(size + 1, &traces, &md);
    assert!(out.status.success(), "{}", stderr(&out));
    // Not a size: refused by the option's parser, naming what it expects.
    let out = hexcue(&[
        "compare".as_ref(),
        "--traces".as_ref(),
        traces.as_os_str(),
        "--max-trace-mb".as_ref(),
        "0".as_ref(),
    ]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("positive number of MB"),
        "{}",
        stderr(&out)
    );

    // Streamed: no limit applies, and the recording attaches the whole trace.
    let mcap = dir.path().join("long.mcap");
    let out = hexcue(&[
        "play".as_ref(),
        "--headless".as_ref(),
        "--algorithms".as_ref(),
        "cwf".as_ref(),
        "--trace".as_ref(),
        trace.as_os_str(),
        "--record".as_ref(),
        mcap.as_os_str(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stdout(&out).contains(&format!("{rows} steps")),
        "{}",
        stdout(&out)
    );
    let buf = std::fs::read(&mcap).unwrap();
    let summary = mcap::Summary::read(&buf).unwrap().expect("a summary");
    let index = summary
        .attachment_indexes
        .iter()
        .find(|a| a.name == "trace.csv.zst")
        .expect("the trace attachment");
    let attached = mcap::read::attachment(&buf, index).unwrap();
    let csv = zstd::decode_all(&attached.data[..]).unwrap();
    assert!(
        csv == std::fs::read(&trace).unwrap(),
        "the attachment is not the trace"
    );
    let out = hexcue(&["review".as_ref(), mcap.as_os_str(), "--headless".as_ref()]);
    assert!(out.status.success(), "{}", stderr(&out));
}

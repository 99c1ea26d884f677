//! Bad recordings: a real recording made by the binary, then cut, scrambled, replaced by a
//! file that is not MCAP, or by an MCAP that is not hexcue's. `review --headless` and
//! `recover` must refuse each with the file and the reason (non-zero exit, no panic), or,
//! for a file cut after its first chunk, review it as unfinished with a warning.

mod common;

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use common::*;

fn scratch() -> PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("recordings-corpus");
        // Emptied once a run: an earlier run's files would be refused as outputs (no --force).
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("the scratch directory can be made");
        dir
    })
    .clone()
}

/// One real recording (the embedded trace, CWF), made once per test binary.
fn real_recording() -> &'static Path {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        let path = scratch().join("real.mcap");
        let out = hexcue(&[
            "play".as_ref(),
            "--headless".as_ref(),
            "--algorithms".as_ref(),
            "cwf".as_ref(),
            "--record".as_ref(),
            path.as_os_str(),
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
        path
    })
}

fn review(path: &Path) -> std::process::Output {
    hexcue(&["review".as_ref(), path.as_os_str(), "--headless".as_ref()])
}

fn recover(input: &Path, output: &Path) -> std::process::Output {
    hexcue(&["recover".as_ref(), input.as_os_str(), output.as_os_str()])
}

/// Steps in a headless table's first line: "trace … profile …  N steps at R Hz".
fn table_steps(out: &std::process::Output) -> usize {
    let text = stdout(out);
    let first = text.lines().next().unwrap_or_default();
    let words: Vec<&str> = first.split_whitespace().collect();
    words
        .iter()
        .position(|w| *w == "steps")
        .and_then(|i| words.get(i.wrapping_sub(1)))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no step count in the table:\n{text}"))
}

/// A refusal: non-zero, the file named, the reason's words present, nothing on stdout.
fn assert_refused(out: &std::process::Output, file: &Path, words: &[&str]) {
    let err = stderr(out);
    assert!(
        !out.status.success(),
        "{} was accepted:\n{err}",
        file.display()
    );
    let name = file.file_name().unwrap().to_string_lossy();
    assert!(
        err.contains(name.as_ref()),
        "the error does not name {name}:\n{err}"
    );
    for w in words {
        assert!(err.contains(w), "{name}: the error lacks `{w}`:\n{err}");
    }
    assert!(stdout(out).is_empty(), "{name}: stdout on failure");
}

#[test]
fn the_whole_recording_reviews_cleanly() {
    let out = review(real_recording());
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(!stderr(&out).contains("not finished"), "{}", stderr(&out));
    assert_eq!(table_steps(&out), 5500);
}

#[test]
fn a_recording_cut_at_every_tenth_is_refused_or_reviewed_as_unfinished() {
    let bytes = std::fs::read(real_recording()).unwrap();
    let full_steps = 5500;
    // Every tenth, plus cuts inside the magic, the header and the first records.
    let mut cuts: Vec<usize> = (0..10).map(|i| bytes.len() * i / 10).collect();
    cuts.extend([1, 7, 8, 9, 20, 100, 1000]);
    let mut reviewed = Vec::new();
    for cut in cuts {
        let path = scratch().join(format!("cut-{cut}.mcap"));
        std::fs::write(&path, &bytes[..cut]).unwrap();
        let out = review(&path);
        let err = stderr(&out);
        if out.status.success() {
            assert!(
                err.contains("cut-") && err.contains("not finished"),
                "cut at {cut}: no warning that the file is unfinished:\n{err}"
            );
            let steps = table_steps(&out);
            assert!(steps < full_steps, "cut at {cut}: {steps} steps");
            reviewed.push((cut, steps));
            let fixed = scratch().join(format!("cut-{cut}-recovered.mcap"));
            let rec = recover(&path, &fixed);
            assert!(rec.status.success(), "recover cut {cut}: {}", stderr(&rec));
            let again = review(&fixed);
            assert!(again.status.success(), "{}", stderr(&again));
            assert!(
                !stderr(&again).contains("not finished"),
                "the recovered copy of cut {cut} is unfinished:\n{}",
                stderr(&again)
            );
            assert_eq!(table_steps(&again), steps, "recovered cut {cut}");
        } else {
            // Only a cut before the first complete chunk may be refused, and it says why.
            let reason = if cut < 8 {
                "not an MCAP file"
            } else {
                "before its first message"
            };
            assert_refused(&out, &path, &[reason]);
            let fixed = scratch().join(format!("cut-{cut}-recovered.mcap"));
            assert_refused(&recover(&path, &fixed), &path, &[reason]);
            assert!(!fixed.exists() || std::fs::metadata(&fixed).unwrap().len() == 0);
        }
    }
    // From 20 % on, the cuts are well past the attachments: each must review, and a longer
    // prefix never reads fewer steps.
    let big: Vec<_> = reviewed
        .iter()
        .filter(|(cut, _)| *cut >= bytes.len() / 5)
        .collect();
    assert!(big.len() >= 8, "{reviewed:?}");
    assert!(big.windows(2).all(|w| w[0].1 <= w[1].1), "{reviewed:?}");
    // At 90 % of the bytes, about 90 % of the steps (the attachments are at the front).
    let last = big.last().unwrap().1;
    assert!(last > full_steps * 8 / 10, "{reviewed:?}");
}

/// xorshift64*: reproducible noise without a dependency.
fn noise(seed: u64, len: usize) -> Vec<u8> {
    let mut s = seed;
    (0..len)
        .map(|_| {
            s ^= s >> 12;
            s ^= s << 25;
            s ^= s >> 27;
            (s.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 56) as u8
        })
        .collect()
}

#[test]
fn random_bytes_are_refused() {
    for (name, bytes) in [
        ("random.mcap", noise(1, 65_536)),
        // Past the magic check, garbage records.
        ("magic-then-random.mcap", {
            let mut b = b"\x89MCAP0\r\n".to_vec();
            b.extend(noise(2, 65_536));
            b
        }),
        // A real header and metadata, then noise where the chunks were.
        ("real-head-random-tail.mcap", {
            let real = std::fs::read(real_recording()).unwrap();
            let mut b = real[..real.len() / 4].to_vec();
            b.extend(noise(3, 200_000));
            b
        }),
    ] {
        let path = scratch().join(name);
        std::fs::write(&path, &bytes).unwrap();
        let out = review(&path);
        if name == "real-head-random-tail.mcap" {
            // What came before the noise is a real recording's: it reviews as unfinished,
            // read up to the noise, which is named as where reading stopped.
            assert!(out.status.success(), "{}", stderr(&out));
            assert!(stderr(&out).contains("not finished"), "{}", stderr(&out));
        } else {
            assert_refused(&out, &path, &[]);
            let err = stderr(&out);
            assert!(
                err.contains("not an MCAP file") || err.contains("damaged MCAP"),
                "{name}: {err}"
            );
            let fixed = scratch().join(format!("{name}.recovered"));
            assert_refused(&recover(&path, &fixed), &path, &[]);
        }
    }
}

#[test]
fn a_file_that_is_not_mcap_is_refused() {
    for (name, bytes) in [
        (
            "profile.mcap",
            std::fs::read(repo().join("profiles/full-flight.toml")).unwrap(),
        ),
        (
            "trace.mcap",
            std::fs::read(repo().join("recordings/traces/landing.csv")).unwrap(),
        ),
        ("empty.mcap", Vec::new()),
    ] {
        let path = scratch().join(name);
        std::fs::write(&path, &bytes).unwrap();
        assert_refused(&review(&path), &path, &["not an MCAP file"]);
        let out = scratch().join(format!("{name}.recovered"));
        assert_refused(&recover(&path, &out), &path, &["not an MCAP file"]);
    }
    let missing = scratch().join("does-not-exist.mcap");
    assert_refused(&review(&missing), &missing, &["cannot open"]);
}

/// A well-formed, finished MCAP with JSON channels that hexcue did not write.
fn foreign_mcap(path: &Path, topics: &[&str]) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = mcap::Writer::new(file).unwrap();
    let schema = w
        .add_schema("imu", "jsonschema", br#"{"type":"object"}"#)
        .unwrap();
    let channels: Vec<u16> = topics
        .iter()
        .map(|t| w.add_channel(schema, t, "json", &BTreeMap::new()).unwrap())
        .collect();
    for k in 0..100u64 {
        for &c in &channels {
            let msg = format!(r#"{{"t":{},"ax":0.1}}"#, k as f64 * 0.01);
            w.write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id: c,
                    sequence: k as u32,
                    log_time: 1_000_000_000 + k * 10_000_000,
                    publish_time: 1_000_000_000 + k * 10_000_000,
                },
                msg.as_bytes(),
            )
            .unwrap();
        }
    }
    w.finish().unwrap();
}

#[test]
fn an_mcap_without_hexcue_topics_is_refused() {
    let path = scratch().join("foreign.mcap");
    foreign_mcap(&path, &["/imu", "/gps"]);
    let words = ["not a hexcue recording", "/aircraft/perceived", "/imu"];
    assert_refused(&review(&path), &path, &words);
    assert_refused(
        &recover(&path, &scratch().join("foreign-recovered.mcap")),
        &path,
        &words,
    );
    // An MCAP with no channel at all says so.
    let empty = scratch().join("no-channels.mcap");
    foreign_mcap(&empty, &[]);
    assert_refused(&review(&empty), &empty, &["no topics"]);
}

/// Copies a finished recording's metadata, attachments and messages into a new file written
/// with `options`, passing each message's data through `data`.
fn transcode(
    src: &Path,
    dst: &Path,
    options: mcap::WriteOptions,
    data: impl Fn(&str, Cow<'static, [u8]>) -> Cow<'static, [u8]>,
) {
    transcode_with(src, dst, options, data, |_| {});
}

/// [`transcode`], passing each attachment through `attachment` too.
fn transcode_with(
    src: &Path,
    dst: &Path,
    options: mcap::WriteOptions,
    data: impl Fn(&str, Cow<'static, [u8]>) -> Cow<'static, [u8]>,
    attachment: impl Fn(&mut mcap::Attachment),
) {
    let bytes = std::fs::read(src).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let file = std::io::BufWriter::new(std::fs::File::create(dst).unwrap());
    let mut w = options.create(file).unwrap();
    for record in mcap::read::LinearReader::new(&bytes).unwrap() {
        if let mcap::records::Record::Metadata(m) = record.unwrap() {
            w.write_metadata(&m).unwrap();
        }
    }
    for a in &summary.attachment_indexes {
        let mut a = mcap::read::attachment(&bytes, a).unwrap();
        attachment(&mut a);
        w.attach(&a).unwrap();
    }
    // In log-time order, as a tool that rewrites a recording through an indexed reader gives
    // them: since format 2 hexcue groups a chunk's messages by topic, and restores the order
    // only within a chunk (docs/recordings.md, "Format 2").
    let mut messages: Vec<_> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| m.unwrap())
        .collect();
    messages.sort_by_key(|m| m.log_time);
    for m in messages {
        let owned: Cow<'static, [u8]> = Cow::Owned(m.data.into_owned());
        w.write(&mcap::Message {
            data: data(&m.channel.topic, owned),
            channel: m.channel,
            sequence: m.sequence,
            log_time: m.log_time,
            publish_time: m.publish_time,
        })
        .unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn an_mcap_with_hexcue_topics_but_bad_messages_is_refused_by_name() {
    // Every `/aircraft` message replaced by JSON of the wrong shape: review must name the
    // topic and what it expected, not panic.
    let path = scratch().join("bad-messages.mcap");
    transcode(
        real_recording(),
        &path,
        mcap::WriteOptions::new(),
        |topic, d| {
            if topic == "/aircraft" {
                Cow::Borrowed(br#"{"t":"soon","k":-1}"#)
            } else {
                d
            }
        },
    );
    assert_refused(&review(&path), &path, &["/aircraft", "expected"]);
}

#[test]
fn an_unchunked_uncompressed_recording_reviews_the_same() {
    // Other MCAP writers (and the fuzzer's seeds, where a CRC would stop every mutation of a
    // message) put messages straight in the data section, without chunks or CRCs.
    let path = scratch().join("unchunked.mcap");
    transcode(
        real_recording(),
        &path,
        mcap::WriteOptions::new()
            .use_chunks(false)
            .compression(None)
            .calculate_data_section_crc(false)
            .calculate_summary_section_crc(false)
            .calculate_attachment_crcs(false),
        |_, d| d,
    );
    let (a, b) = (review(real_recording()), review(&path));
    assert!(b.status.success(), "{}", stderr(&b));
    assert_eq!(stdout(&a), stdout(&b));
    // HEXCUE_WRITE_FUZZ_SEED=1 also writes the fuzzer's seed of this form (docs/reliability.md).
    if std::env::var_os("HEXCUE_WRITE_FUZZ_SEED").is_some() {
        let seeds = repo().join("fuzz/seeds/recording");
        transcode(
            &seeds.join("tiny.mcap"),
            &seeds.join("tiny-unchunked.mcap"),
            mcap::WriteOptions::new()
                .use_chunks(false)
                .compression(None)
                .calculate_data_section_crc(false)
                .calculate_summary_section_crc(false)
                .calculate_attachment_crcs(false),
            |_, d| d,
        );
    }
}

#[test]
fn a_recording_with_its_trace_uncompressed_reviews_the_same() {
    // Recordings written before the trace attachment was compressed hold `trace.csv` as
    // text; they must still review, recover and check against their SHA-256.
    let path = scratch().join("plain-trace.mcap");
    transcode_with(
        real_recording(),
        &path,
        mcap::WriteOptions::new(),
        |_, d| d,
        |a| {
            if a.name == "trace.csv.zst" {
                a.name = "trace.csv".into();
                a.media_type = "text/csv".into();
                a.data = Cow::Owned(zstd::decode_all(&a.data[..]).unwrap());
            }
        },
    );
    let (a, b) = (review(real_recording()), review(&path));
    assert!(b.status.success(), "{}", stderr(&b));
    assert_eq!(stdout(&a), stdout(&b));
    assert_eq!(stderr(&a), stderr(&b), "no notice about the trace either");
    let recovered = scratch().join("plain-trace-recovered.mcap");
    let out = recover(&path, &recovered);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(stdout(&a), stdout(&review(&recovered)));
}

#[test]
fn a_trace_attachment_that_does_not_decompress_is_refused_by_name() {
    let path = scratch().join("bad-trace-zst.mcap");
    transcode_with(
        real_recording(),
        &path,
        mcap::WriteOptions::new(),
        |_, d| d,
        |a| {
            if a.name == "trace.csv.zst" {
                a.data = Cow::Borrowed(common::trace_header(false).as_bytes());
            }
        },
    );
    assert_refused(&review(&path), &path, &["trace.csv.zst", "decompress"]);
}

#[test]
fn recordings_the_fuzzer_found_are_refused_by_name() {
    // tests/corpus/recordings: inputs that once panicked the reader (docs/reliability.md).
    let dir = repo().join("tests/corpus/recordings");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert!(!files.is_empty());
    for file in files {
        assert_refused(&review(&file), &file, &["damaged MCAP"]);
        let out = scratch().join("fuzz-found-recovered.mcap");
        assert_refused(&recover(&file, &out), &file, &["damaged MCAP"]);
    }
}

/// A finished recording of the landing (6,000 steps, CWF), made once per test binary.
fn landing_recording() -> &'static Path {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        let path = scratch().join("landing.mcap");
        let out = play_recorded(
            &repo().join("recordings/traces/landing.csv"),
            "cwf",
            &path,
            None,
        );
        assert!(out.status.success(), "{}", stderr(&out));
        path
    })
}

/// The numbers after `words` in `text`'s first line that has them: "steps 2900–2999" gives
/// (2900, 2999).
fn range_after(text: &str, words: &str) -> (u64, u64) {
    let at = text
        .find(words)
        .unwrap_or_else(|| panic!("no `{words}` in:\n{text}"));
    let rest = &text[at + words.len()..];
    let digits: Vec<u64> = rest
        .split(|c: char| !c.is_ascii_digit())
        .filter(|w| !w.is_empty())
        .take(2)
        .map(|w| w.parse().unwrap())
        .collect();
    (digits[0], digits[1])
}

/// The offset, 64 bytes into its compressed records, of the first chunk record (opcode 0x06)
/// that starts at or after `at`, walking the records as the MCAP specification lays them
/// out: the 8-byte magic, then an opcode byte and a little-endian u64 length before each
/// record's body.
fn chunk_body_after(bytes: &[u8], at: usize) -> usize {
    let mut pos = 8;
    while pos + 9 <= bytes.len() {
        let op = bytes[pos];
        let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap()) as usize;
        if op == 0x06 && pos >= at {
            // The chunk's header: start and end times, uncompressed size, CRC, the
            // compression's name and the records' length, then the records.
            let name_len = u32::from_le_bytes(bytes[pos + 37..pos + 41].try_into().unwrap());
            let records = pos + 41 + name_len as usize + 8;
            assert!(
                len > 64 + 2048,
                "a chunk of {len} bytes is too small to damage"
            );
            return records + 64;
        }
        pos += 9 + len;
    }
    panic!("no chunk after byte {at}");
}

/// 2 kB of noise over a chunk in the middle of a finished recording: `recover` skips the damaged
/// chunk, keeps every intact one after it, names the steps, times and topics lost and exits
/// non-zero; `review`, `export` and `plot` read the rest with the same warning.
#[test]
fn a_recording_damaged_in_its_middle_keeps_its_intact_chunks() {
    let bytes = std::fs::read(landing_recording()).unwrap();
    let full_steps = 6000;
    let whole = review(landing_recording());
    assert!(whole.status.success(), "{}", stderr(&whole));
    assert_eq!(table_steps(&whole), full_steps);

    let mut damaged = bytes.clone();
    // Within the first chunk that starts past the file's middle: the middle itself may fall
    // in a message index between chunks, whose damage loses no message.
    let middle = chunk_body_after(&bytes, bytes.len() / 2);
    damaged[middle..middle + 2048].copy_from_slice(&noise(7, 2048));
    let path = scratch().join("landing-damaged.mcap");
    std::fs::write(&path, &damaged).unwrap();

    let fixed = scratch().join("landing-damaged-recovered.mcap");
    let out = recover(&path, &fixed);
    let err = stderr(&out);
    assert!(
        !out.status.success(),
        "damage was not reported as a loss:\n{err}"
    );
    assert!(
        !err.contains("not finished"),
        "a finished file damaged afterwards called unfinished:\n{err}"
    );
    assert!(
        err.contains("damaged") && err.contains("landing-damaged.mcap"),
        "{err}"
    );
    // What was lost: the steps and their times, and that every topic lost them.
    let (first, last) = range_after(&err, "skipped steps ");
    assert!(
        first > 0 && last >= first && last < full_steps as u64,
        "{err}"
    );
    let lost = last - first + 1;
    assert!(
        err.contains(&format!("({lost} steps)")) || err.contains("(1 step)"),
        "{err}"
    );
    assert!(err.contains("t = ") && err.contains("every topic"), "{err}");
    assert!(
        err.contains(&format!("{lost} steps lost")) || lost == 1,
        "{err}"
    );

    // The copy holds every step but the lost ones, and is itself intact.
    let again = review(&fixed);
    assert!(again.status.success(), "{}", stderr(&again));
    assert!(!stderr(&again).contains("damaged"), "{}", stderr(&again));
    let kept = table_steps(&again);
    assert!(
        kept * 10 >= full_steps * 9,
        "kept {kept} of {full_steps} steps"
    );
    assert_eq!(kept as u64 + lost, full_steps as u64, "{err}");

    // The damaged file itself reads to its end, with a warning that names the loss, and
    // then exits non-zero (as `recover` does): a script must not take the table, the
    // export or the figure for the whole flight.
    let lost_line = |out: &std::process::Output, what: &str| {
        let err = stderr(out);
        assert!(!out.status.success(), "{err}");
        assert!(
            err.contains(&format!(
                "steps lost in 1 damaged part; {what} holds every intact one"
            )),
            "{err}"
        );
    };
    let direct = review(&path);
    let warn = stderr(&direct);
    lost_line(&direct, "the summary");
    assert_eq!(table_steps(&direct), kept);
    assert!(
        warn.contains("warning") && warn.contains("skipped steps"),
        "{warn}"
    );
    assert!(!warn.contains("not finished"), "{warn}");

    let csv = scratch().join("landing-damaged-aircraft.csv");
    let out = hexcue(&[
        "export".as_ref(),
        path.as_os_str(),
        "--topic".as_ref(),
        "/aircraft".as_ref(),
        "-o".as_ref(),
        csv.as_os_str(),
    ]);
    lost_line(&out, "the export");
    assert!(stderr(&out).contains("skipped steps"), "{}", stderr(&out));
    let rows = std::fs::read_to_string(&csv).unwrap().lines().count() - 1;
    assert!(rows * 10 >= full_steps * 9, "exported {rows} rows");

    let svg = scratch().join("landing-damaged.svg");
    let out = hexcue(&[
        "plot".as_ref(),
        path.as_os_str(),
        "-o".as_ref(),
        svg.as_os_str(),
    ]);
    lost_line(&out, "the figure");
    assert!(stderr(&out).contains("skipped steps"), "{}", stderr(&out));
    assert!(svg.exists(), "the figure of the intact steps is written");
}

/// A write that fails in the middle of a run (the file size limit, as a full disk would):
/// the recorder, on its own thread, stops, and the run ends with its error, which names the
/// file and the cause.
#[test]
fn a_write_error_in_the_middle_of_a_run_names_the_file_and_the_cause() {
    use std::os::unix::process::CommandExt;
    const LIMIT_BYTES: u64 = 300_000;
    let path = scratch().join("too-large.mcap");
    let mut command = std::process::Command::new(env!("CARGO_BIN_EXE_hexcue"));
    command
        .args(["play", "--headless", "--algorithms", "cwf", "--trace"])
        .arg(repo().join("recordings/traces/landing.csv"))
        .arg("--record")
        .arg(&path);
    // SAFETY: between fork and exec only two system calls, both async-signal-safe.
    unsafe {
        command.pre_exec(|| {
            let limit = libc::rlimit {
                rlim_cur: LIMIT_BYTES,
                rlim_max: LIMIT_BYTES,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            // A write past the limit then fails with EFBIG instead of killing the process.
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            Ok(())
        });
    }
    let out = command.output().unwrap();
    let err = stderr(&out);
    assert!(!out.status.success(), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        err.contains(&format!("{}: cannot write the recording", path.display())),
        "{err}"
    );
    assert!(err.contains("File too large"), "{err}");
    // Stopped in the middle: the attachments and the first chunks were written.
    let written = std::fs::metadata(&path).unwrap().len();
    assert!(
        written > LIMIT_BYTES / 2 && written <= LIMIT_BYTES,
        "{written} bytes"
    );
}

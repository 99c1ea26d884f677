//! The played trace on its way into a recording's attachment: hashed and compressed on a
//! thread of its own as the trace is read, so that a headless run starts stepping while
//! level 16's optimal parser is still at work (docs/performance.md, "The trace's compression
//! beside the steps"); the recorder's thread waits for it ([`TraceCopy::finish`]) before it
//! writes the file's first record.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, SyncSender};
use std::thread::JoinHandle;

use sha2::{Digest, Sha256};

use super::{shown, trace_level, RecordingError};

/// Blocks of trace text in flight between the reader and the compressing thread: a few
/// reads ahead, so that neither waits for the other's every block, and memory stays flat
/// however long the trace (the blocks are the reader's, typically 64 KB).
const BLOCKS_IN_FLIGHT: usize = 16;

/// A trace on its way into a recording: compressed (one zstd frame) into a scratch file
/// and hashed (SHA-256) on a thread of its own as its bytes are written in, so that whoever
/// reads the trace feeds both in the same pass and nothing grows with its length.
/// [`TraceCopy::finish`] waits for that thread and gives the [`CompressedTrace`] to attach;
/// a copy given up is removed.
pub struct TraceCopy {
    path: PathBuf,
    tx: Option<SyncSender<Vec<u8>>>,
    worker: Option<JoinHandle<io::Result<String>>>,
}

impl TraceCopy {
    /// A scratch file beside the recording at `recording` (its name + `.trace.zst`) for the
    /// trace file `trace`, whose length sets the zstd level.
    pub fn beside(recording: &Path, trace: &Path) -> Result<Self, RecordingError> {
        let mut name = recording.as_os_str().to_owned();
        name.push(".trace.zst");
        let text_bytes = std::fs::metadata(trace).ok().map(|m| m.len());
        Self::to(PathBuf::from(name), text_bytes)
    }

    /// A scratch file at `path`.
    pub fn to(path: PathBuf, text_bytes: Option<u64>) -> Result<Self, RecordingError> {
        let failed = |error| RecordingError::Io {
            path: shown(&path),
            action: "create the compressed trace",
            error,
        };
        let level = trace_level(text_bytes);
        let out = File::create(&path)
            .and_then(|file| zstd::stream::Encoder::new(BufWriter::new(file), level))
            .map_err(failed)?;
        let (tx, rx) = mpsc::sync_channel(BLOCKS_IN_FLIGHT);
        let worker = std::thread::Builder::new()
            .name("trace-zstd".into())
            .spawn(move || compress(out, rx))
            .map_err(failed)?;
        Ok(TraceCopy {
            path,
            tx: Some(tx),
            worker: Some(worker),
        })
    }

    /// The compressing thread's result, once it has ended (its sender dropped first).
    fn join(&mut self) -> io::Result<String> {
        self.tx = None;
        match self.worker.take() {
            Some(worker) => match worker.join() {
                Ok(result) => result,
                Err(panic) => std::panic::resume_unwind(panic),
            },
            None => Err(io::Error::other("the compressed trace is finished")),
        }
    }

    /// Waits for the compressing thread to end the zstd frame and sync the file: the
    /// attachment and the hash of what was written.
    pub fn finish(mut self) -> Result<CompressedTrace, RecordingError> {
        let path = std::mem::take(&mut self.path);
        match self.join() {
            Ok(sha256) => Ok(CompressedTrace { path, sha256 }),
            Err(error) => {
                let _ = std::fs::remove_file(&path);
                Err(RecordingError::Io {
                    path: shown(&path),
                    action: "write the compressed trace",
                    error,
                })
            }
        }
    }
}

/// The compressing thread: every block in order into the encoder and the hash, until the
/// reader hangs up; then the frame ended and the file synced. Returns the hash (hex).
fn compress(
    mut out: zstd::stream::Encoder<'static, BufWriter<File>>,
    rx: Receiver<Vec<u8>>,
) -> io::Result<String> {
    let mut hasher = Sha256::new();
    for block in rx {
        out.write_all(&block)?;
        hasher.update(&block);
    }
    let file = out
        .finish()
        .and_then(|w| w.into_inner().map_err(|e| e.into_error()))?;
    file.sync_all()?;
    Ok(hasher
        .finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect())
}

impl Write for TraceCopy {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let sent = match &self.tx {
            Some(tx) => tx.send(buf.to_vec()).is_ok(),
            None => return Err(io::Error::other("the compressed trace is finished")),
        };
        if sent {
            return Ok(buf.len());
        }
        // The thread hung up: only on a write error, which is the one to report.
        Err(match self.join() {
            Err(error) => error,
            Ok(_) => io::Error::other("the trace's compression stopped"),
        })
    }

    fn flush(&mut self) -> io::Result<()> {
        // The blocks are the thread's; `finish` is what puts them in the file.
        Ok(())
    }
}

impl Drop for TraceCopy {
    fn drop(&mut self) {
        // Given up before `finish` (the trace was refused): the thread ended, and the
        // scratch file goes too.
        if !self.path.as_os_str().is_empty() {
            let _ = self.join();
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// A trace compressed into a scratch file by a [`TraceCopy`], with the SHA-256 of its text;
/// the file is removed when this is dropped, attached or not.
pub struct CompressedTrace {
    pub(super) path: PathBuf,
    pub(super) sha256: String,
}

impl Drop for CompressedTrace {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
mod tests {
    use std::io::Read;

    use super::*;

    /// The scratch file holds the text written in, in order, whatever the blocks' sizes,
    /// and the hash is the text's.
    #[test]
    fn the_copy_is_the_text_and_its_hash_in_blocks_of_any_size() {
        let dir = tempfile::tempdir().unwrap();
        let text: Vec<u8> = (0..200_000u32)
            .flat_map(|i| format!("{},{}\n", i, i * 7 % 13).into_bytes())
            .collect();
        let mut copy = TraceCopy::to(dir.path().join("t.zst"), Some(text.len() as u64)).unwrap();
        let mut at = 0;
        for size in [1, 7, 65_536, 3, 100_000].iter().cycle() {
            if at == text.len() {
                break;
            }
            let end = (at + size).min(text.len());
            copy.write_all(&text[at..end]).unwrap();
            at = end;
        }
        let trace = copy.finish().unwrap();
        let mut back = Vec::new();
        zstd::stream::Decoder::new(File::open(&trace.path).unwrap())
            .unwrap()
            .read_to_end(&mut back)
            .unwrap();
        assert!(back == text, "the text came back changed");
        let hex: String = Sha256::digest(&text)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        assert_eq!(trace.sha256, hex);
        let path = trace.path.clone();
        drop(trace);
        assert!(!path.exists(), "the scratch file outlived its trace");
    }

    /// A copy given up mid-way leaves no scratch file and no thread behind.
    #[test]
    fn a_copy_given_up_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.zst");
        let mut copy = TraceCopy::to(path.clone(), None).unwrap();
        copy.write_all(b"t,fx\n0,1\n").unwrap();
        drop(copy);
        assert!(!path.exists());
    }
}

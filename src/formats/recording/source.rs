//! Records of a recording as they are in the file, for the reader, the JSON export and
//! recovery alike.

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

use mcap::records::Record;
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use mcap::McapError;

use super::{shown, RecordingError};

/// Bytes fed to the reader at once: memory follows the file's actual content, never a
/// length field that a damaged file may make huge.
pub(super) const READ_SIZE: usize = 64 * 1024;
/// Largest record the reader accepts (a trace CSV attachment is the largest by far).
const RECORD_LIMIT: usize = 256 << 20;

/// Records of a file, in file order, as the sans-io linear reader finds them: chunks are
/// opened, and each is checked whole against its CRC before any of its records is given out,
/// so a torn last chunk yields nothing rather than garbage.
pub(super) struct RecordSource {
    file: File,
    reader: LinearReader,
    pub(super) bytes: u64,
}

pub(super) enum SourceError {
    Io(io::Error),
    Mcap(McapError),
}

impl RecordSource {
    /// A read error as the reader's error: I/O as such, anything else as damage after the
    /// bytes read so far.
    pub(super) fn error(&self, path: &str, e: SourceError) -> RecordingError {
        match e {
            SourceError::Io(error) => RecordingError::Io {
                path: path.to_string(),
                action: "read the recording",
                error,
            },
            SourceError::Mcap(error) => RecordingError::Damaged {
                path: path.to_string(),
                bytes: self.bytes,
                error,
            },
        }
    }

    pub(super) fn open(path: &Path) -> Result<Self, RecordingError> {
        let file = File::open(path).map_err(|error| RecordingError::Io {
            path: shown(path),
            action: "open the recording",
            error,
        })?;
        let options = LinearReaderOptions::default()
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(RECORD_LIMIT);
        Ok(RecordSource {
            file,
            reader: LinearReader::new_with_options(options),
            bytes: 0,
        })
    }

    /// The next record; `None` once the end magic has been read.
    pub(super) fn next_record(&mut self) -> Option<Result<Record<'static>, SourceError>> {
        loop {
            match self.reader.next_event()? {
                Err(e) => return Some(Err(SourceError::Mcap(e))),
                Ok(LinearReadEvent::ReadRequest(need)) => {
                    let buf = self.reader.insert(need.clamp(1, READ_SIZE));
                    let read = loop {
                        match self.file.read(buf) {
                            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                            other => break other,
                        }
                    };
                    match read {
                        Ok(n) => {
                            self.reader.notify_read(n);
                            self.bytes += n as u64;
                        }
                        Err(e) => return Some(Err(SourceError::Io(e))),
                    }
                }
                Ok(LinearReadEvent::Record { opcode, data }) => {
                    if opcode == mcap::records::op::ATTACHMENT {
                        if let Err(e) = check_attachment_body(data) {
                            return Some(Err(SourceError::Mcap(e)));
                        }
                    }
                    return Some(
                        mcap::parse_record(opcode, data)
                            .map(Record::into_owned)
                            .map_err(SourceError::Mcap),
                    );
                }
            }
        }
    }
}

/// Checks that an attachment record's body holds its fixed fields, two strings, its data
/// and its CRC. `mcap::parse_record` (0.26) slices `body[header_len..len - 4]` without that
/// check and panics on a body too short for its header: found by fuzzing the reader
/// (docs/reliability.md). A damaged file must be an error, never a panic.
pub(super) fn check_attachment_body(body: &[u8]) -> Result<(), McapError> {
    let too_short = |header: u64| McapError::BadAttachmentLength {
        header,
        available: body.len() as u64,
    };
    let u32_at = |at: usize| -> Option<u64> {
        let b = body.get(at..at.checked_add(4)?)?;
        Some(u64::from(u32::from_le_bytes(b.try_into().ok()?)))
    };
    // log_time, create_time, then the name and media type (u32 length + bytes each).
    let mut at: usize = 16;
    for _ in 0..2 {
        let len = u32_at(at).ok_or_else(|| too_short(0))?;
        at = at
            .checked_add(4)
            .and_then(|a| a.checked_add(usize::try_from(len).ok()?))
            .ok_or_else(|| too_short(len))?;
    }
    let data_len = body
        .get(at..at.saturating_add(8))
        .and_then(|b| b.try_into().ok())
        .map(u64::from_le_bytes)
        .ok_or_else(|| too_short(0))?;
    let end = (at as u64)
        .checked_add(8)
        .and_then(|e| e.checked_add(data_len))
        .and_then(|e| e.checked_add(4))
        .ok_or_else(|| too_short(data_len))?;
    if end > body.len() as u64 {
        return Err(too_short(data_len));
    }
    Ok(())
}

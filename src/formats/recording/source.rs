//! Records of a recording as they are in the file, for the reader, the JSON export and
//! recovery alike.
//!
//! A damaged chunk does not end the reading: the source skips it, says which bytes it
//! skipped, and goes on with the next chunk that checks against its CRC, so that 2 kB of
//! garbage in the middle of a finished file costs the steps of the chunk(s) it hit, not
//! everything after them.

use std::collections::VecDeque;
use std::fs::File;
use std::io::{self, Read, Seek, SeekFrom};
use std::path::Path;

use mcap::records::{op, Record};
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use mcap::McapError;

use super::{shown, RecordingError};

/// Bytes fed to the reader at once: memory follows the file's actual content, never a
/// length field that a damaged file may make huge.
pub(super) const READ_SIZE: usize = 64 * 1024;
/// Largest record the reader accepts (a trace CSV attachment is the largest by far).
const RECORD_LIMIT: usize = 256 << 20;
/// Bytes of a chunk record before its compression string: opcode, length, start and end
/// times, uncompressed size, CRC and the string's length.
const CHUNK_HEAD: usize = 1 + 8 + 8 + 8 + 8 + 4 + 4;
/// A Data End record as hexcue's writer leaves it: opcode, length 4 (its CRC follows).
const DATA_END_HEAD: [u8; 9] = [op::DATA_END, 4, 0, 0, 0, 0, 0, 0, 0];

/// Bytes the source could not read and stepped over: `[from_byte, to_byte)`.
#[derive(Debug)]
pub(super) struct Skip {
    pub from_byte: u64,
    pub to_byte: u64,
    /// What was wrong at `from_byte`.
    pub error: McapError,
    /// Whether reading went on after the skip (false: the rest of the file was unreadable).
    pub resumed: bool,
}

pub(super) enum Item {
    Record(Record<'static>),
    Skipped(Skip),
}

/// Records of a file, in file order. Chunks are read whole and checked against their CRC
/// before any of their records is given out, so a torn or damaged chunk yields nothing
/// rather than garbage; the source then looks for the next intact chunk.
pub(super) struct RecordSource {
    file: File,
    file_len: u64,
    /// Reads the file's top-level records; chunks come out whole and are opened here.
    reader: LinearReader,
    /// Where the next top-level record starts.
    offset: u64,
    /// Records of the chunk being given out.
    queued: VecDeque<Record<'static>>,
    /// Whether the end magic was read after the footer.
    pub(super) ended: bool,
    done: bool,
    /// Bytes of the file read so far (where reading is).
    pub(super) bytes: u64,
}

pub(super) enum SourceError {
    Io(io::Error),
    Mcap(McapError),
}

fn top_level_reader(skip_start_magic: bool) -> LinearReader {
    LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_skip_start_magic(skip_start_magic)
            .with_emit_chunks(true)
            .with_record_length_limit(RECORD_LIMIT),
    )
}

/// A chunk record (`opcode, length, body`) opened: its records, once its CRC checks.
fn open_chunk(record: &[u8]) -> Result<Vec<Record<'static>>, McapError> {
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_skip_start_magic(true)
            .with_skip_end_magic(true)
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(RECORD_LIMIT),
    );
    let mut fed = false;
    let mut records = Vec::new();
    while let Some(event) = reader.next_event() {
        match event? {
            LinearReadEvent::ReadRequest(_) if fed => reader.notify_read(0),
            LinearReadEvent::ReadRequest(_) => {
                reader.insert(record.len()).copy_from_slice(record);
                reader.notify_read(record.len());
                fed = true;
            }
            LinearReadEvent::Record { opcode, data } => {
                records.push(parse(opcode, data)?);
            }
        }
    }
    in_log_time_order(&mut records);
    Ok(records)
}

/// A chunk's messages in log-time order, after its other records (schemas and channels,
/// which the messages use): hexcue writes a chunk's messages grouped by topic
/// (`writer.rs`, `Pending`), and MCAP lets a chunk hold them in any order. Stable, so the
/// messages of one step keep their order, and a chunk written in time order (every file
/// written before) is unchanged.
fn in_log_time_order(records: &mut [Record<'static>]) {
    records.sort_by_key(|r| match r {
        Record::Message { header, .. } => (1, header.log_time),
        _ => (0, 0),
    });
}

/// A record's body parsed, for the opcodes the MCAP specification defines.
fn parse(opcode: u8, data: &[u8]) -> Result<Record<'static>, McapError> {
    if !(op::HEADER..=op::DATA_END).contains(&opcode) {
        // Garbage read as a record's start: the caller resynchronises.
        return Err(McapError::UnexpectedEoc);
    }
    if opcode == op::ATTACHMENT {
        check_attachment_body(data)?;
    }
    mcap::parse_record(opcode, data).map(Record::into_owned)
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    b.get(at..at + 8)
        .and_then(|s| s.try_into().ok())
        .map_or(u64::MAX, u64::from_le_bytes)
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
        let io_error = |error| RecordingError::Io {
            path: shown(path),
            action: "open the recording",
            error,
        };
        let file = File::open(path).map_err(io_error)?;
        let file_len = file.metadata().map_err(io_error)?.len();
        Ok(RecordSource {
            file,
            file_len,
            reader: top_level_reader(false),
            offset: mcap::MAGIC.len() as u64,
            queued: VecDeque::new(),
            ended: false,
            done: false,
            bytes: 0,
        })
    }

    /// The next record or skipped stretch; `None` at the end of the file.
    pub(super) fn next_record(&mut self) -> Option<Result<Item, SourceError>> {
        loop {
            if let Some(record) = self.queued.pop_front() {
                return Some(Ok(Item::Record(record)));
            }
            if self.done {
                return None;
            }
            let event = match self.reader.next_event() {
                None => {
                    self.done = true;
                    self.ended = true;
                    return None;
                }
                Some(event) => event,
            };
            let at = self.offset;
            let found = match event {
                Err(McapError::BadMagic) if at == mcap::MAGIC.len() as u64 && self.bytes <= at => {
                    self.done = true;
                    return Some(Err(SourceError::Mcap(McapError::BadMagic)));
                }
                Err(e) => Err(e),
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
                        Err(e) => {
                            self.done = true;
                            return Some(Err(SourceError::Io(e)));
                        }
                    }
                    continue;
                }
                Ok(LinearReadEvent::Record { opcode, data }) => {
                    self.offset += 9 + data.len() as u64;
                    if opcode == op::CHUNK {
                        let mut record = Vec::with_capacity(9 + data.len());
                        record.push(op::CHUNK);
                        record.extend_from_slice(&(data.len() as u64).to_le_bytes());
                        record.extend_from_slice(data);
                        open_chunk(&record).map(|records| {
                            self.queued.extend(records);
                            None
                        })
                    } else {
                        parse(opcode, data).map(Some)
                    }
                }
            };
            match found {
                Ok(Some(record)) => return Some(Ok(Item::Record(record))),
                Ok(None) => {}
                Err(error) => {
                    return Some(match self.resync(at, error) {
                        Ok(skip) => Ok(Item::Skipped(skip)),
                        Err(e) => {
                            self.done = true;
                            Err(SourceError::Io(e))
                        }
                    })
                }
            }
        }
    }

    /// After damage at `from`: the next intact chunk (or the Data End record) and reading
    /// restarted there, or the end of the file when there is none.
    fn resync(&mut self, from: u64, error: McapError) -> io::Result<Skip> {
        const WINDOW: usize = 64 * 1024;
        let mut window = vec![0u8; WINDOW];
        let mut start = from + 1;
        while start < self.file_len {
            self.file.seek(SeekFrom::Start(start))?;
            let n = read_full(&mut self.file, &mut window)?;
            for (i, &b) in window[..n].iter().enumerate() {
                let at = start + i as u64;
                if b == op::DATA_END {
                    let mut head = [0u8; 9];
                    self.file.seek(SeekFrom::Start(at))?;
                    if read_full(&mut self.file, &mut head)? == 9 && head == DATA_END_HEAD {
                        self.restart(at)?;
                        return Ok(Skip {
                            from_byte: from,
                            to_byte: at,
                            error,
                            resumed: true,
                        });
                    }
                } else if b == op::CHUNK {
                    if let Some(records) = self.chunk_at(at)? {
                        let len = 9 + u64_at(&self.head_buf(at)?, 1);
                        self.restart(at + len)?;
                        self.queued.extend(records);
                        return Ok(Skip {
                            from_byte: from,
                            to_byte: at,
                            error,
                            resumed: true,
                        });
                    }
                }
            }
            if n < WINDOW {
                break;
            }
            start += n as u64;
        }
        self.done = true;
        self.bytes = self.file_len;
        Ok(Skip {
            from_byte: from,
            to_byte: self.file_len,
            error,
            resumed: false,
        })
    }

    fn head_buf(&mut self, at: u64) -> io::Result<[u8; CHUNK_HEAD]> {
        let mut head = [0u8; CHUNK_HEAD];
        self.file.seek(SeekFrom::Start(at))?;
        let n = read_full(&mut self.file, &mut head)?;
        if n < CHUNK_HEAD {
            head[0] = 0;
        }
        Ok(head)
    }

    /// The records of an intact chunk starting at `at`, if one does: a plausible header,
    /// then the whole chunk checked against its CRC.
    fn chunk_at(&mut self, at: u64) -> io::Result<Option<Vec<Record<'static>>>> {
        let head = self.head_buf(at)?;
        if head[0] != op::CHUNK {
            return Ok(None);
        }
        let len = u64_at(&head, 1);
        let uncompressed = u64_at(&head, 25);
        let crc = u32::from_le_bytes([head[33], head[34], head[35], head[36]]);
        let compression_len = u32::from_le_bytes([head[37], head[38], head[39], head[40]]);
        let plausible = len <= RECORD_LIMIT as u64
            && at.saturating_add(9).saturating_add(len) <= self.file_len
            && uncompressed <= RECORD_LIMIT as u64
            && crc != 0
            && matches!(compression_len, 0 | 3 | 4)
            && len >= (CHUNK_HEAD - 9) as u64 + u64::from(compression_len) + 8;
        if !plausible {
            return Ok(None);
        }
        let mut record = vec![0u8; 9 + len as usize];
        self.file.seek(SeekFrom::Start(at))?;
        if read_full(&mut self.file, &mut record)? < record.len() {
            return Ok(None);
        }
        Ok(open_chunk(&record).ok())
    }

    /// Whether the file ends with the MCAP magic, as a file closed properly does.
    pub(super) fn tail_is_magic(&mut self) -> bool {
        let magic = mcap::MAGIC.len() as u64;
        if self.file_len < 2 * magic {
            return false;
        }
        let mut tail = [0u8; 8];
        self.file
            .seek(SeekFrom::Start(self.file_len - magic))
            .is_ok()
            && read_full(&mut self.file, &mut tail).is_ok_and(|n| n == tail.len())
            && tail[..] == mcap::MAGIC[..]
    }

    /// Top-level reading from `at` on.
    fn restart(&mut self, at: u64) -> io::Result<()> {
        self.file.seek(SeekFrom::Start(at))?;
        self.reader = top_level_reader(true);
        self.offset = at;
        self.bytes = at;
        Ok(())
    }
}

fn read_full(file: &mut File, buf: &mut [u8]) -> io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match file.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
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

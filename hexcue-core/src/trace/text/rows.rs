//! A trace's rows: read line by line, checked, converted to SI and put on the engine's grid,
//! whole or streamed.

use super::columns::*;
use super::*;

/// Parses a trace (native or JSBSim CSV) and puts it on the uniform grid of `target_rate_hz`.
/// `source_name` names the file in every error; `name` is the trace's name for the user.
pub fn parse_trace(
    text: &str,
    source_name: &str,
    name: &str,
    target_rate_hz: f64,
) -> Result<Trace, TraceError> {
    parse_measured(text, source_name, name, target_rate_hz).map(|(trace, _)| trace)
}

/// [`parse_trace`], also returning the rate the CSV was written at (1 / median step), which
/// the sidecar is checked against ([`attach_info`]) and resampling has replaced. The text goes
/// through the same streaming reader as a trace file ([`read_trace`]).
pub fn parse_measured(
    text: &str,
    source_name: &str,
    name: &str,
    target_rate_hz: f64,
) -> Result<(Trace, f64), TraceError> {
    read_trace(&|| Ok(text.as_bytes()), source_name, name, target_rate_hz)
}

/// A trace read whole into memory from a source `open` gives from its start each time it is
/// called (a file opened again, bytes already in memory): a first pass ([`scan`]) checks every
/// row, a second puts the samples on the grid of `target_rate_hz` ([`GridSamples`]). At most
/// [`MAX_TRACE_SAMPLES`] samples. Also returns the rate the CSV was written at, as
/// [`parse_measured`] does; `name` is the trace's name for the user, `source_name` names the
/// source in every error.
pub fn read_trace<R: BufRead>(
    open: &dyn Fn() -> Result<R, TraceError>,
    source_name: &str,
    name: &str,
    target_rate_hz: f64,
) -> Result<(Trace, f64), TraceError> {
    let plan = scan(open, source_name, name, target_rate_hz, MAX_TRACE_SAMPLES)?;
    let mut grid = GridSamples::new(open()?, &plan)?;
    let mut samples = Vec::with_capacity(plan.len);
    while let Some(s) = grid.next_sample()? {
        samples.push(s);
    }
    let measured = plan.measured_rate_hz;
    let trace = Trace {
        name: name.to_string(),
        rate_hz: target_rate_hz,
        samples,
        info: None,
        notices: plan.notices,
    };
    Ok((trace, measured))
}

/// The lines of a trace, one at a time: each checked for length before it is decoded, so
/// that a huge line costs no more than the limit, and for UTF-8. Blank lines are skipped.
pub(super) struct Lines<R> {
    pub(super) reader: R,
    pub(super) line_no: usize,
    /// Bytes read so far: where the next line starts.
    pub(super) offset: u64,
    pub(super) buf: Vec<u8>,
    pub(super) source_name: String,
}

impl<R: BufRead> Lines<R> {
    pub(super) fn new(reader: R, source_name: &str) -> Self {
        Lines {
            reader,
            line_no: 0,
            offset: 0,
            buf: Vec::new(),
            source_name: source_name.to_string(),
        }
    }

    /// The next non-blank line (without its line ending) and its 1-based number.
    pub(super) fn next_line(&mut self) -> Result<Option<(usize, &str)>, TraceError> {
        let ctx = Ctx {
            source_name: &self.source_name,
        };
        // The line's byte range in `buf`: found in the loop, borrowed after it.
        let range = loop {
            self.buf.clear();
            let n = (&mut self.reader)
                .take(MAX_LINE_BYTES as u64 + 2)
                .read_until(b'\n', &mut self.buf)
                .map_err(|error| TraceError::Io {
                    source_name: self.source_name.clone(),
                    error,
                })?;
            if n == 0 {
                return Ok(None);
            }
            self.offset += n as u64;
            self.line_no += 1;
            let mut end = self.buf.len() - usize::from(self.buf.ends_with(b"\n"));
            let bom = "\u{feff}".as_bytes();
            let start = if self.line_no == 1 && self.buf.starts_with(bom) {
                bom.len()
            } else {
                0
            };
            if end - start.min(end) > MAX_LINE_BYTES {
                return Err(ctx.at(
                    self.line_no,
                    1,
                    None,
                    TraceErrorKind::LineTooLong,
                    format!(
                        "line longer than {MAX_LINE_BYTES} bytes; expected a CSV row of numbers (is this a trace?)"
                    ),
                ));
            }
            if end > start && self.buf[end - 1] == b'\r' {
                end -= 1;
            }
            let bytes = &self.buf[start.min(end)..end];
            match std::str::from_utf8(bytes) {
                // Blank lines carry nothing; trailing ones are what most editors leave behind.
                Ok(line) if line.trim().is_empty() => continue,
                Ok(_) => break start.min(end)..end,
                Err(e) => {
                    let valid = &bytes[..e.valid_up_to()];
                    return Err(ctx.at(
                        self.line_no,
                        String::from_utf8_lossy(valid).chars().count() + 1,
                        None,
                        TraceErrorKind::NotUtf8,
                        "not UTF-8 text; expected a CSV file".to_string(),
                    ));
                }
            }
        };
        let line = std::str::from_utf8(&self.buf[range]).unwrap_or_default();
        Ok(Some((self.line_no, line)))
    }
}

/// The data rows of a trace, one at a time, each checked as it is read: fields, numbers,
/// magnitudes and strictly increasing time.
pub(super) struct TraceRows<R> {
    pub(super) lines: Lines<R>,
    pub(super) layout: Layout,
    pub(super) header_line: usize,
    /// Time and line of the previous row.
    pub(super) prev: Option<(f64, usize)>,
    pub(super) rows: usize,
    /// Most rows read: [`MAX_TRACE_SAMPLES`] where the trace is held in memory, none where it
    /// is streamed.
    pub(super) max_rows: usize,
}

impl<R: BufRead> TraceRows<R> {
    /// Reads up to the header; an empty file is refused here.
    pub(super) fn new(reader: R, source_name: &str) -> Result<Self, TraceError> {
        let mut lines = Lines::new(reader, source_name);
        let ctx = Ctx { source_name };
        let Some((header_line, header)) = lines.next_line()? else {
            return Err(ctx.file(
                TraceErrorKind::Empty,
                format!("empty file; expected a header line `{NATIVE_HEADER}` and rows of numbers"),
            ));
        };
        let layout = layout(header, header_line, &ctx)?;
        Ok(TraceRows {
            lines,
            layout,
            header_line,
            prev: None,
            rows: 0,
            max_rows: MAX_TRACE_SAMPLES,
        })
    }

    /// The next row as read (time not shifted) and its line.
    pub(super) fn next_row(&mut self) -> Result<Option<(AircraftSample, usize)>, TraceError> {
        let source_name = self.lines.source_name.clone();
        let ctx = Ctx {
            source_name: &source_name,
        };
        let Some((line_no, line)) = self.lines.next_line()? else {
            return Ok(None);
        };
        if self.rows >= self.max_rows {
            return Err(ctx.at(
                line_no,
                1,
                None,
                TraceErrorKind::TooManySamples,
                format!(
                    "more than {} rows, the most a trace held in memory may have (11 h at \
                     100 Hz; `compare` and `tune` hold their traces); expected a shorter trace, \
                     or `hexcue play`, which streams a trace of any length",
                    self.max_rows
                ),
            ));
        }
        let layout = &self.layout;
        let sample = parse_row(line, line_no, layout, &ctx)?;
        if let Some((prev_t, prev_line)) = self.prev {
            if sample.t_s <= prev_t {
                let what = if sample.t_s == prev_t {
                    "repeats"
                } else {
                    "goes back from"
                };
                let (at, _) = fields(line).nth(layout.time.column).unwrap_or((0, ""));
                return Err(ctx.at(
                    line_no,
                    char_column(line, at),
                    Some(&layout.time.header),
                    TraceErrorKind::TimeNotIncreasing,
                    format!(
                        "column `{}`: time {} s {what} {} s on line {prev_line}; expected strictly increasing time",
                        layout.time.header, sample.t_s, prev_t
                    ),
                ));
            }
        }
        self.prev = Some((sample.t_s, line_no));
        self.rows += 1;
        Ok(Some((sample, line_no)))
    }
}

/// What a first pass over a trace found: enough to put it on the grid while streaming it a
/// second time, holding two rows at a time.
#[derive(Clone, Debug)]
pub struct TracePlan {
    /// The trace's name for the user.
    pub name: String,
    /// The source, as errors name it.
    pub source_name: String,
    /// The grid's rate (Hz).
    pub rate_hz: f64,
    /// Samples on the grid.
    pub len: usize,
    /// Data rows in the file.
    pub(super) rows: usize,
    /// Time of the first row, subtracted from every row (s).
    pub(super) t0: f64,
    /// Every row already on the grid: taken as they are, timestamps snapped.
    pub(super) on_grid: bool,
    /// 1 / the median step of the rows (Hz).
    pub measured_rate_hz: f64,
    /// What was done to the input on the way in, as [`Trace::notices`].
    pub notices: Vec<String>,
    /// The sidecar, when one was found and read.
    pub info: Option<TraceInfo>,
    /// Most samples on the grid and rows in the file: [`MAX_TRACE_SAMPLES`] for a trace held
    /// in memory, `usize::MAX` for one streamed.
    pub(super) max_samples: usize,
}

/// First pass: every row checked, and the statistics the grid needs ([`TracePlan`]). Memory is
/// a map of the distinct time steps (a handful for a trace written at a fixed rate), not the
/// rows. `open` gives the source from its start; it is called a second time only to find the
/// line of a gap in a refused trace. `max_samples` bounds the rows and the grid:
/// [`MAX_TRACE_SAMPLES`] for a trace held in memory, `usize::MAX` for one streamed (a grid
/// of more than 1000 samples a row is refused even then).
pub fn scan<R: BufRead>(
    open: &dyn Fn() -> Result<R, TraceError>,
    source_name: &str,
    name: &str,
    target_rate_hz: f64,
    max_samples: usize,
) -> Result<TracePlan, TraceError> {
    let ctx = Ctx { source_name };
    if !(target_rate_hz.is_finite() && target_rate_hz > 0.0 && target_rate_hz <= MAX_TARGET_RATE_HZ)
    {
        return Err(ctx.file(
            TraceErrorKind::BadRate,
            format!(
                "cannot resample to {target_rate_hz} Hz; expected a rate in (0, {MAX_TARGET_RATE_HZ}] Hz"
            ),
        ));
    }
    let mut rows = TraceRows::new(open()?, source_name)?;
    rows.max_rows = max_samples;
    let mut steps: std::collections::BTreeMap<u64, usize> = std::collections::BTreeMap::new();
    let (mut min_step, mut max_step) = (f64::INFINITY, 0.0f64);
    let (mut first, mut last) = (None::<f64>, 0.0);
    let mut grid_ok = true;
    let mut units = UnitStats::new();
    let mut k = 0usize;
    while let Some((s, _)) = rows.next_row()? {
        units.push(&s);
        let t0 = *first.get_or_insert(s.t_s);
        if k > 0 {
            // Time strictly increases, so steps are positive and their bits order as they do.
            let step = s.t_s - last;
            *steps.entry(step.to_bits()).or_default() += 1;
            min_step = min_step.min(step);
            max_step = max_step.max(step);
        }
        let shifted = s.t_s - t0;
        grid_ok &=
            ((shifted - k as f64 / target_rate_hz) * target_rate_hz).abs() <= GRID_TOLERANCE_STEPS;
        last = s.t_s;
        k += 1;
    }
    let n = rows.rows;
    let header_line = rows.header_line;
    let mut notices = std::mem::take(&mut rows.layout.notices);
    let time_header = rows.layout.time.header.clone();
    if n < 2 {
        return Err(ctx.file(
            TraceErrorKind::TooFewRows,
            format!(
                "{n} data row(s) after the header on line {header_line}; expected at least two"
            ),
        ));
    }
    if let Some(warning) = check_units(&units, &rows.layout, &ctx)? {
        notices.push(warning);
    }
    let t0 = first.unwrap_or(0.0);
    // The median step: the value of rank (n−1)/2 among the n−1 steps, in order.
    let mid = (n - 1) / 2;
    let mut seen = 0;
    let median_step = steps
        .iter()
        .find_map(|(bits, count)| {
            seen += count;
            (seen > mid).then(|| f64::from_bits(*bits))
        })
        .unwrap_or(max_step);
    if max_step > MAX_GAP_FACTOR * median_step {
        // Found again on a second pass, for its lines; only a refused file pays for it.
        let mut rows = TraceRows::new(open()?, source_name)?;
        let mut prev: Option<(f64, usize)> = None;
        while let Some((s, line)) = rows.next_row()? {
            if let Some((pt, pl)) = prev {
                let gap = s.t_s - pt;
                if gap > MAX_GAP_FACTOR * median_step {
                    return Err(ctx.at(
                        line,
                        1,
                        Some(&time_header),
                        TraceErrorKind::Gap,
                        format!(
                            "gap of {} s before this row (line {pl} is at {pt} s, the median step is {} s); expected no step longer than {MAX_GAP_FACTOR}× the median",
                            seconds(gap),
                            seconds(median_step),
                        ),
                    ));
                }
            }
            prev = Some((s.t_s, line));
        }
    }
    if t0 != 0.0 {
        notices.push(format!("time starts at {t0} s; shifted to start at 0"));
    }
    let duration_s = last - t0;
    let last_k = (duration_s * target_rate_hz + GRID_TOLERANCE_STEPS).floor();
    // Streamed, a trace may be as long as it likes, but not a few rows stretched over a huge
    // span: beyond the in-memory limit, a grid of more than MAX_UPSAMPLING samples a row is
    // refused (two rows a million seconds apart would be 10^8 interpolated samples).
    let sparse =
        last_k + 1.0 > MAX_TRACE_SAMPLES as f64 && last_k + 1.0 > MAX_UPSAMPLING * n as f64;
    if last_k + 1.0 > max_samples as f64 || sparse {
        let e = ResampleError::TooManySamples {
            duration_s,
            rate_hz: target_rate_hz,
        };
        return Err(ctx.file(
            TraceErrorKind::TooManySamples,
            format!("{e}; expected a shorter trace"),
        ));
    }
    let len = last_k as usize + 1;
    if len < 2 {
        return Err(ctx.file(
            TraceErrorKind::TooFewRows,
            format!(
                "{duration_s} s of data is shorter than one step at {} Hz; expected at least two samples",
                format_hz(target_rate_hz)
            ),
        ));
    }
    let on_grid = grid_ok && len == n;
    if !on_grid {
        let irregular = if max_step - min_step > IRREGULAR_SPREAD * median_step {
            " irregular"
        } else {
            ""
        };
        notices.push(format!(
            "resampled from ~{} Hz{irregular} to {} Hz by linear interpolation",
            format_hz(1.0 / median_step),
            format_hz(target_rate_hz)
        ));
    }
    Ok(TracePlan {
        name: name.to_string(),
        source_name: source_name.to_string(),
        rate_hz: target_rate_hz,
        len,
        rows: n,
        t0,
        on_grid,
        measured_rate_hz: 1.0 / median_step,
        max_samples,
        notices,
        info: None,
    })
}

/// Second pass: the samples on the uniform grid t_k = k / rate, two rows in memory. Values
/// are those of [`resample_uniform`](crate::trace::resample_uniform), bit for bit: a trace on the grid keeps its values and
/// only its timestamps are snapped; another is linearly interpolated.
pub struct GridSamples<R> {
    pub(super) rows: TraceRows<R>,
    pub(super) rate_hz: f64,
    pub(super) len: usize,
    pub(super) rows_total: usize,
    pub(super) t0: f64,
    pub(super) on_grid: bool,
    pub(super) k: usize,
    /// The rows around the next grid time (interpolation), and the index of `a`.
    pub(super) a: Option<AircraftSample>,
    pub(super) b: Option<AircraftSample>,
    pub(super) j: usize,
}

impl<R: BufRead> GridSamples<R> {
    /// The samples of `plan`'s trace from `reader`, the source [`scan`] read, from its start.
    pub fn new(reader: R, plan: &TracePlan) -> Result<Self, TraceError> {
        Ok(GridSamples {
            rows: TraceRows {
                max_rows: plan.max_samples,
                ..TraceRows::new(reader, &plan.source_name)?
            },
            rate_hz: plan.rate_hz,
            len: plan.len,
            rows_total: plan.rows,
            t0: plan.t0,
            on_grid: plan.on_grid,
            k: 0,
            a: None,
            b: None,
            j: 0,
        })
    }

    /// Index of the next sample.
    pub fn position(&self) -> usize {
        self.k
    }

    /// Where the stream is, to come back to with [`GridSamples::restore`].
    pub fn mark(&self) -> GridMark {
        GridMark {
            k: self.k,
            a: self.a,
            b: self.b,
            j: self.j,
            prev: self.rows.prev,
            rows: self.rows.rows,
            line_no: self.rows.lines.line_no,
            offset: self.rows.lines.offset,
        }
    }

    pub(super) fn row(&mut self) -> Result<AircraftSample, TraceError> {
        match self.rows.next_row()? {
            Some((mut s, _)) => {
                if self.t0 != 0.0 {
                    s.t_s -= self.t0;
                }
                Ok(s)
            }
            None => Err(TraceError::File {
                source_name: self.rows.lines.source_name.clone(),
                kind: TraceErrorKind::TooFewRows,
                message: "the file has fewer rows than when it was first read; expected it unchanged during the run".into(),
            }),
        }
    }

    /// The next sample on the grid; `None` after the last. A source that changed since it
    /// was scanned may give an error still.
    pub fn next_sample(&mut self) -> Result<Option<AircraftSample>, TraceError> {
        if self.k >= self.len {
            return Ok(None);
        }
        let t = self.k as f64 / self.rate_hz;
        self.k += 1;
        if self.on_grid {
            let s = self.row()?;
            return Ok(Some(AircraftSample { t_s: t, ..s }));
        }
        if self.a.is_none() {
            self.a = Some(self.row()?);
            self.b = Some(self.row()?);
        }
        while self.j + 2 < self.rows_total && self.b.is_some_and(|b| b.t_s <= t) {
            self.a = self.b;
            self.b = Some(self.row()?);
            self.j += 1;
        }
        let (Some(a), Some(b)) = (self.a, self.b) else {
            return Ok(None);
        };
        Ok(Some(lerp_sample(&a, &b, t)))
    }
}

/// A position in a [`GridSamples`] stream: its sample index, the rows it interpolates
/// between, and the byte and line where its reader continues.
#[derive(Clone, Debug)]
pub struct GridMark {
    pub(super) k: usize,
    pub(super) a: Option<AircraftSample>,
    pub(super) b: Option<AircraftSample>,
    pub(super) j: usize,
    pub(super) prev: Option<(f64, usize)>,
    pub(super) rows: usize,
    pub(super) line_no: usize,
    pub(super) offset: u64,
}

impl GridMark {
    /// Index of the sample the stream gives next from here.
    pub fn position(&self) -> usize {
        self.k
    }
}

impl<R: BufRead + std::io::Seek> GridSamples<R> {
    /// Back (or forward) to a mark this stream took, without reading what lies between.
    pub fn restore(&mut self, m: &GridMark) -> Result<(), TraceError> {
        let lines = &mut self.rows.lines;
        lines
            .reader
            .seek(std::io::SeekFrom::Start(m.offset))
            .map_err(|error| TraceError::Io {
                source_name: lines.source_name.clone(),
                error,
            })?;
        lines.offset = m.offset;
        lines.line_no = m.line_no;
        self.rows.prev = m.prev;
        self.rows.rows = m.rows;
        self.k = m.k;
        self.a = m.a;
        self.b = m.b;
        self.j = m.j;
        Ok(())
    }
}

/// Most grid samples a row of a streamed trace may become once the grid is beyond the
/// in-memory limit ([`MAX_TRACE_SAMPLES`]): a 1 Hz log resampled to 100 Hz is 100.
const MAX_UPSAMPLING: f64 = 1000.0;

/// Refuses a trace whose [`UnitStats`] show a unit or sign mistake, naming its columns; says
/// what could not be checked (returned as a notice naming the file).
pub(super) fn check_units(
    stats: &UnitStats,
    layout: &Layout,
    ctx: &Ctx,
) -> Result<Option<String>, TraceError> {
    let header = |q: Quantity| {
        layout.sources[q.index()]
            .as_ref()
            .map_or(q.native_name().to_string(), |s| s.header.clone())
    };
    use Quantity::*;
    let names = UnitNames {
        columns: [Fx, Fy, Fz, P, Q, R, Phi, Theta, Psi].map(header),
        whole: "the trace",
        has_attitude: [Phi, Theta, Psi]
            .iter()
            .all(|q| layout.sources[q.index()].is_some()),
    };
    match stats.judge(&names) {
        UnitJudgement::Mistake(message) => Err(ctx.file(TraceErrorKind::Units, message)),
        UnitJudgement::Unchecked(message) => {
            Ok(Some(format!("warning: {}: {message}", ctx.source_name)))
        }
        UnitJudgement::Believable => Ok(None),
    }
}

pub(super) fn parse_row(
    line: &str,
    line_no: usize,
    layout: &Layout,
    ctx: &Ctx,
) -> Result<AircraftSample, TraceError> {
    let count = fields(line).count();
    if count != layout.column_count {
        if count == 1 {
            if let Some(found) = foreign_delimiter(line, false) {
                return Err(ctx.at(
                    line_no,
                    1,
                    None,
                    TraceErrorKind::Delimiter,
                    format!("expected comma-separated values, found {found}"),
                ));
            }
        }
        return Err(ctx.at(
            line_no,
            1,
            None,
            TraceErrorKind::FieldCount,
            format!(
                "{count} field(s); expected {} as in the header",
                layout.column_count
            ),
        ));
    }
    let mut values = [0.0; 10];
    let row: Vec<(usize, &str)> = fields(line).collect();
    for q in QUANTITIES {
        let Some(source) = &layout.sources[q.index()] else {
            continue;
        };
        let (at, text) = row[source.column];
        let text = unquote(text);
        let located = |kind, message: String| {
            ctx.at(
                line_no,
                char_column(line, at),
                Some(&source.header),
                kind,
                format!("column `{}`: {message}", source.header),
            )
        };
        let raw: f64 = text.parse().map_err(|_| {
            located(
                TraceErrorKind::NotANumber,
                if text.is_empty() {
                    "empty field; expected a number".to_string()
                } else {
                    format!("expected a number, found {}", shown(text))
                },
            )
        })?;
        if !raw.is_finite() {
            return Err(located(
                TraceErrorKind::NotFinite,
                format!("{}; expected a finite number", shown(text)),
            ));
        }
        let value = raw * source.scale;
        let (limit, unit) = q.limit();
        // The value is finite here, so this comparison is total.
        if value.abs() > limit {
            let hint = match q {
                Quantity::Fx | Quantity::Fy | Quantity::Fz => " (a file in other units?)",
                Quantity::P | Quantity::Q | Quantity::R => " (a file in deg/s?)",
                _ => "",
            };
            return Err(located(
                TraceErrorKind::OutOfRange,
                format!(
                    "{value} {unit} is beyond ±{limit} {unit}; expected a believable value{hint}"
                ),
            ));
        }
        values[q.index()] = value;
    }
    Ok(AircraftSample {
        t_s: values[0],
        specific_force_mps2: Vector3::new(values[1], values[2], values[3]),
        angular_velocity_radps: Vector3::new(values[4], values[5], values[6]),
        attitude_rad: Vector3::new(values[7], values[8], values[9]),
    })
}

/// A duration computed from the trace's times, to six significant digits with no trailing
/// zeros: a difference of two times read from text is `0.009999999999999787`, not `0.01`.
fn seconds(s: f64) -> String {
    if !s.is_finite() || s == 0.0 {
        return format!("{s}");
    }
    let decimals = (5 - s.abs().log10().floor() as i32).clamp(0, 12) as usize;
    let text = format!("{s:.decimals$}");
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    }
}

#[cfg(test)]
mod seconds_tests {
    use super::seconds;

    #[test]
    fn durations_read_as_written() {
        assert_eq!(seconds(0.009999999999999787), "0.01");
        assert_eq!(seconds(2.5000000000001), "2.5");
        assert_eq!(seconds(120.0), "120");
        assert_eq!(seconds(0.0012345678), "0.00123457");
        assert_eq!(seconds(12345.678), "12345.7");
    }
}

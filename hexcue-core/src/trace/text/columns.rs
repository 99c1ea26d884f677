//! A trace's header: which column holds which quantity, in which unit (native names and
//! JSBSim's), and the messages that point at a line and column as an editor shows them.

use super::*;

/// The quantities of a trace, in the column order of the native header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Quantity {
    T,
    Fx,
    Fy,
    Fz,
    P,
    Q,
    R,
    Phi,
    Theta,
    Psi,
}

pub(super) const QUANTITIES: [Quantity; 10] = [
    Quantity::T,
    Quantity::Fx,
    Quantity::Fy,
    Quantity::Fz,
    Quantity::P,
    Quantity::Q,
    Quantity::R,
    Quantity::Phi,
    Quantity::Theta,
    Quantity::Psi,
];

/// Header of the native format, in the documented order.
pub const NATIVE_HEADER: &str = "t,fx,fy,fz,p,q,r,phi,theta,psi";

impl Quantity {
    pub(super) fn native_name(self) -> &'static str {
        match self {
            Quantity::T => "t",
            Quantity::Fx => "fx",
            Quantity::Fy => "fy",
            Quantity::Fz => "fz",
            Quantity::P => "p",
            Quantity::Q => "q",
            Quantity::R => "r",
            Quantity::Phi => "phi",
            Quantity::Theta => "theta",
            Quantity::Psi => "psi",
        }
    }

    /// Attitude is optional: the algorithms do not use it, the console only shows it.
    pub(super) fn required(self) -> bool {
        !matches!(self, Quantity::Phi | Quantity::Theta | Quantity::Psi)
    }

    /// Largest believable magnitude, in SI, and its unit for messages.
    pub(super) fn limit(self) -> (f64, &'static str) {
        match self {
            Quantity::T => (MAX_TIME_S, "s"),
            Quantity::Fx | Quantity::Fy | Quantity::Fz => (MAX_SPECIFIC_FORCE_MPS2, "m/s²"),
            Quantity::P | Quantity::Q | Quantity::R => (MAX_RATE_RADPS, "rad/s"),
            Quantity::Phi | Quantity::Theta | Quantity::Psi => (MAX_ATTITUDE_RAD, "rad"),
        }
    }

    pub(super) fn index(self) -> usize {
        self as usize
    }
}

/// One JSBSim header JSBSim may write for a quantity, with the factor to SI.
pub(super) struct Alias {
    pub(super) header: &'static str,
    pub(super) scale: f64,
    pub(super) conversion: &'static str,
}

pub(super) const fn alias(header: &'static str, scale: f64, conversion: &'static str) -> Alias {
    Alias {
        header,
        scale,
        conversion,
    }
}

/// JSBSim headers for each quantity, best first. Property names appear as written by
/// `<property>` output (fully qualified `/fdm/jsbsim/...`, or relative in older versions,
/// which is what remains after the prefix is stripped); `P (deg/s)` and `Phi (deg)` are the
/// captions of the built-in `<rates>` and `<propagate>` output groups.
pub(super) fn jsbsim_aliases(q: Quantity) -> &'static [Alias] {
    const FT: &str = "ft/s² × 0.3048";
    const NORM: &str = "g × 9.80665";
    const DEG: &str = "deg × π/180";
    const NONE: &str = "";
    const TIME: &[Alias] = &[
        alias("time", 1.0, NONE),
        alias("simulation/sim-time-sec", 1.0, NONE),
    ];
    const FX: &[Alias] = &[
        alias("accelerations/a-pilot-x-ft_sec2", FT_TO_M, FT),
        alias("accelerations/n-pilot-x-norm", G_MPS2, NORM),
    ];
    const FY: &[Alias] = &[
        alias("accelerations/a-pilot-y-ft_sec2", FT_TO_M, FT),
        alias("accelerations/n-pilot-y-norm", G_MPS2, NORM),
    ];
    const FZ: &[Alias] = &[
        alias("accelerations/a-pilot-z-ft_sec2", FT_TO_M, FT),
        alias("accelerations/n-pilot-z-norm", G_MPS2, NORM),
    ];
    const P: &[Alias] = &[
        alias("velocities/p-rad_sec", 1.0, NONE),
        alias("velocities/p-deg_sec", DEG_TO_RAD, DEG),
        alias("p (deg/s)", DEG_TO_RAD, DEG),
    ];
    const Q: &[Alias] = &[
        alias("velocities/q-rad_sec", 1.0, NONE),
        alias("velocities/q-deg_sec", DEG_TO_RAD, DEG),
        alias("q (deg/s)", DEG_TO_RAD, DEG),
    ];
    const R: &[Alias] = &[
        alias("velocities/r-rad_sec", 1.0, NONE),
        alias("velocities/r-deg_sec", DEG_TO_RAD, DEG),
        alias("r (deg/s)", DEG_TO_RAD, DEG),
    ];
    const PHI: &[Alias] = &[
        alias("attitude/phi-rad", 1.0, NONE),
        alias("attitude/roll-rad", 1.0, NONE),
        alias("attitude/phi-deg", DEG_TO_RAD, DEG),
        alias("phi (deg)", DEG_TO_RAD, DEG),
    ];
    const THETA: &[Alias] = &[
        alias("attitude/theta-rad", 1.0, NONE),
        alias("attitude/pitch-rad", 1.0, NONE),
        alias("attitude/theta-deg", DEG_TO_RAD, DEG),
        alias("theta (deg)", DEG_TO_RAD, DEG),
        alias("tht (deg)", DEG_TO_RAD, DEG),
    ];
    const PSI: &[Alias] = &[
        alias("attitude/psi-rad", 1.0, NONE),
        alias("attitude/heading-true-rad", 1.0, NONE),
        alias("attitude/psi-deg", DEG_TO_RAD, DEG),
        alias("psi (deg)", DEG_TO_RAD, DEG),
    ];
    match q {
        Quantity::T => TIME,
        Quantity::Fx => FX,
        Quantity::Fy => FY,
        Quantity::Fz => FZ,
        Quantity::P => P,
        Quantity::Q => Q,
        Quantity::R => R,
        Quantity::Phi => PHI,
        Quantity::Theta => THETA,
        Quantity::Psi => PSI,
    }
}

/// Where a quantity is read from: header column, factor to SI, and the header's text.
#[derive(Clone, Debug)]
pub(super) struct Source {
    pub(super) column: usize,
    pub(super) scale: f64,
    pub(super) header: String,
}

/// A header as compared: trimmed, unquoted, lower case, without JSBSim's property root.
pub(super) fn normalise_header(field: &str) -> String {
    let f = unquote(field.trim()).to_ascii_lowercase();
    let f = f.strip_prefix("/fdm/jsbsim/").unwrap_or(&f);
    f.trim_start_matches('/').to_string()
}

pub(super) fn unquote(field: &str) -> &str {
    field
        .strip_prefix('"')
        .and_then(|f| f.strip_suffix('"'))
        .unwrap_or(field)
}

/// Context for building located errors.
pub(super) struct Ctx<'a> {
    pub(super) source_name: &'a str,
}

impl Ctx<'_> {
    pub(super) fn at(
        &self,
        line: usize,
        column: usize,
        column_name: Option<&str>,
        kind: TraceErrorKind,
        message: String,
    ) -> TraceError {
        TraceError::At {
            source_name: self.source_name.to_string(),
            line,
            column,
            column_name: column_name.map(str::to_string),
            kind,
            message,
        }
    }

    pub(super) fn file(&self, kind: TraceErrorKind, message: String) -> TraceError {
        TraceError::File {
            source_name: self.source_name.to_string(),
            kind,
            message,
        }
    }
}

/// 1-based column of a byte offset within a line, counted in characters as an editor does.
pub(super) fn char_column(line: &str, byte_offset: usize) -> usize {
    line.get(..byte_offset.min(line.len()))
        .map_or(1, |s| s.chars().count() + 1)
}

/// Fields of a row with the byte offset of each field's first non-blank character.
pub(super) fn fields(line: &str) -> impl Iterator<Item = (usize, &str)> {
    let mut start = 0;
    line.split(',').map(move |raw| {
        let lead = raw.len() - raw.trim_start().len();
        let at = start + lead;
        start += raw.len() + 1;
        (at, raw.trim())
    })
}

/// The delimiter a line seems to use instead of commas, if it is clearly one. Spaces count
/// only between several numbers (a data row) or several names (`header`): a sentence is not
/// a space-separated row.
pub(super) fn foreign_delimiter(line: &str, header: bool) -> Option<&'static str> {
    let body = line.trim();
    let found = [(';', "';'"), ('\t', "tab"), ('|', "'|'")]
        .into_iter()
        .find(|(c, _)| body.contains(*c))
        .map(|(_, name)| name);
    found.or_else(|| {
        let tokens: Vec<&str> = body.split_whitespace().collect();
        let spaced =
            tokens.len() > 1 && (header || tokens.iter().all(|t| t.parse::<f64>().is_ok()));
        spaced.then_some("spaces")
    })
}

/// Shows a user's text in a message, shortened: it may be a 64 kB line.
pub(super) fn shown(text: &str) -> String {
    const MAX: usize = 40;
    if text.chars().count() <= MAX {
        format!("`{text}`")
    } else {
        format!("`{}…`", text.chars().take(MAX).collect::<String>())
    }
}

pub(super) fn format_hz(rate: f64) -> String {
    if (rate - rate.round()).abs() < 1e-3 {
        format!("{rate:.0}")
    } else {
        format!("{rate:.2}")
    }
}

/// The columns a header maps to, and the notices that mapping deserves.
pub(super) struct Layout {
    pub(super) sources: [Option<Source>; 10],
    /// The time column, which is required and so always among `sources`.
    pub(super) time: Source,
    pub(super) column_count: usize,
    pub(super) notices: Vec<String>,
}

pub(super) fn layout(header: &str, line: usize, ctx: &Ctx) -> Result<Layout, TraceError> {
    let raw: Vec<(usize, &str)> = fields(header).collect();
    if raw.len() == 1 {
        if let Some(found) = foreign_delimiter(header, true) {
            return Err(ctx.at(
                line,
                1,
                None,
                TraceErrorKind::Delimiter,
                format!(
                    "expected comma-separated values, found {found}; the header should be `{NATIVE_HEADER}`"
                ),
            ));
        }
    }
    let names: Vec<String> = raw.iter().map(|(_, f)| normalise_header(f)).collect();
    let native = names.iter().any(|n| n == "t");
    // A header with the native names of the motion columns is native even when its time
    // column is misnamed (`time` for `t`): the missing column is then `t`, not a JSBSim one.
    let native_motion = ["fx", "fy", "fz", "p", "q", "r"]
        .iter()
        .filter(|want| names.iter().any(|n| n == *want))
        .count()
        >= 4;
    let jsbsim = !native
        && !native_motion
        && (names.first().is_some_and(|n| n == "time") || names.iter().any(|n| n.contains('/')));

    let mut sources: [Option<Source>; 10] = Default::default();
    let mut converted = Vec::new();
    for q in QUANTITIES {
        let candidates: Vec<(&str, f64, &str)> = if jsbsim {
            jsbsim_aliases(q)
                .iter()
                .map(|a| (a.header, a.scale, a.conversion))
                .collect()
        } else {
            vec![(q.native_name(), 1.0, "")]
        };
        let mut found = None;
        for (want, scale, conversion) in candidates {
            let hits: Vec<usize> = (0..names.len()).filter(|&i| names[i] == want).collect();
            if hits.len() > 1 {
                let (at, text) = raw[hits[1]];
                return Err(ctx.at(
                    line,
                    char_column(header, at),
                    Some(text),
                    TraceErrorKind::DuplicateColumn,
                    format!(
                        "column {} appears twice (columns {} and {}); expected each column once",
                        shown(text),
                        hits[0] + 1,
                        hits[1] + 1
                    ),
                ));
            }
            if let Some(&i) = hits.first() {
                found = Some((i, scale, conversion));
                break;
            }
        }
        match found {
            Some((column, scale, conversion)) => {
                let header_text = unquote(raw[column].1).to_string();
                if jsbsim && q != Quantity::T {
                    converted.push(if conversion.is_empty() {
                        format!("{} ← {header_text}", q.native_name())
                    } else {
                        format!("{} ← {header_text} ({conversion})", q.native_name())
                    });
                }
                sources[q.index()] = Some(Source {
                    column,
                    scale,
                    header: header_text,
                });
            }
            None if q.required() => {
                let expected = if jsbsim {
                    let names: Vec<String> =
                        jsbsim_aliases(q).iter().map(|a| shown(a.header)).collect();
                    format!(
                        "a JSBSim column for {} ({})",
                        q.native_name(),
                        names.join(" or ")
                    )
                } else {
                    let hint = if q == Quantity::T {
                        names
                            .iter()
                            .zip(&raw)
                            .find(|(n, _)| {
                                ["time", "time_s", "t_s", "times", "tt", "sim-time-sec"]
                                    .contains(&n.as_str())
                            })
                            .map(|(_, (_, text))| {
                                format!(" (rename column {} to `t`)", shown(unquote(text)))
                            })
                            .unwrap_or_default()
                    } else {
                        String::new()
                    };
                    format!("the columns `{NATIVE_HEADER}` (phi, theta, psi optional){hint}")
                };
                return Err(ctx.at(
                    line,
                    1,
                    Some(q.native_name()),
                    TraceErrorKind::MissingColumn,
                    format!("missing column `{}`; expected {expected}", q.native_name()),
                ));
            }
            None => {}
        }
    }

    let mut notices = Vec::new();
    if jsbsim {
        notices.push(format!(
            "read as JSBSim CSV output: {}",
            converted.join(", ")
        ));
    }
    let missing_attitude: Vec<&str> = [Quantity::Phi, Quantity::Theta, Quantity::Psi]
        .into_iter()
        .filter(|q| sources[q.index()].is_none())
        .map(Quantity::native_name)
        .collect();
    if !missing_attitude.is_empty() {
        notices.push(format!(
            "no {} column: shown as zero",
            missing_attitude.join(", ")
        ));
    }
    let used = sources.iter().flatten().count();
    if names.len() > used {
        notices.push(format!("ignored {} other column(s)", names.len() - used));
    }
    let Some(time) = sources[Quantity::T.index()].clone() else {
        // Required columns were checked above; this keeps the type honest without a panic.
        return Err(ctx.at(
            line,
            1,
            Some("t"),
            TraceErrorKind::MissingColumn,
            format!("missing column `t`; expected the columns `{NATIVE_HEADER}`"),
        ));
    };
    Ok(Layout {
        sources,
        time,
        column_count: raw.len(),
        notices,
    })
}

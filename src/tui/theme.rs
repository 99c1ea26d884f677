//! Colours for terminals reached over SSH: the 16 named ANSI colours only (the user's terminal
//! palette decides what they look like), or none at all when `NO_COLOR` is set. Every state
//! is also written as a word or symbol, so nothing is lost without colour.

use ratatui::style::{Color, Modifier, Style};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Theme {
    pub color: bool,
}

impl Theme {
    /// Colour unless `NO_COLOR` is set to anything non-empty (no-color.org).
    pub fn from_env() -> Self {
        let no_color = std::env::var_os("NO_COLOR").is_some_and(|v| !v.is_empty());
        Theme { color: !no_color }
    }

    pub const ANSI16: Theme = Theme { color: true };
    pub const NO_COLOR: Theme = Theme { color: false };

    fn fg(&self, c: Color) -> Style {
        if self.color {
            Style::new().fg(c)
        } else {
            Style::new()
        }
    }

    /// Bold survives NO_COLOR: it is emphasis, not colour.
    pub fn title(&self) -> Style {
        self.fg(Color::Cyan).add_modifier(Modifier::BOLD)
    }
    pub fn dim(&self) -> Style {
        self.fg(Color::DarkGray)
    }
    pub fn text(&self) -> Style {
        Style::new()
    }
    pub fn key(&self) -> Style {
        self.fg(Color::Yellow).add_modifier(Modifier::BOLD)
    }
    pub fn ok(&self) -> Style {
        self.fg(Color::Green)
    }
    pub fn warn(&self) -> Style {
        self.fg(Color::Yellow)
    }
    pub fn crit(&self) -> Style {
        self.fg(Color::LightRed).add_modifier(Modifier::BOLD)
    }
    pub fn recording(&self) -> Style {
        self.fg(Color::LightRed).add_modifier(Modifier::BOLD)
    }
    /// The perceived reference in the charts.
    pub fn reference(&self) -> Style {
        self.fg(Color::White)
    }
    /// The simulator's perceived signal in the charts.
    pub fn perceived(&self) -> Style {
        self.fg(Color::LightCyan)
    }
    /// An algorithm's line in the overlaid charts (`v`): the hue of its colour in figures
    /// and Foxglove (`channels::algorithm_rgb`: blue, orange, green), among the 16 named
    /// colours; each also has its own marker, so that it reads without colour.
    pub fn algorithm(&self, id: hexcue_core::mca::AlgorithmId) -> Style {
        use hexcue_core::mca::AlgorithmId;
        self.fg(match id {
            AlgorithmId::Smpc => Color::LightBlue,
            AlgorithmId::Mpc => Color::LightMagenta,
            AlgorithmId::Cwf => Color::LightGreen,
        })
    }
    /// The perception-threshold band around the reference in the overlaid charts.
    pub fn band(&self) -> Style {
        self.fg(Color::DarkGray)
    }
    pub fn gauge(&self) -> Style {
        self.fg(Color::Green)
    }
    pub fn border(&self) -> Style {
        self.fg(Color::Blue)
    }
}

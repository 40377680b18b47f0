//! `[[label]]` text as the scene file gives it: where a label sits, its text with
//! placeholders, and what they stand for in a frame. Drawing them is
//! `output::overlay`'s; this module sits below the scene and the output so that both
//! can name a label.

/// Where a label sits in the picture.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Position {
    /// Top left corner.
    TopLeft,
    /// Top edge, centred.
    Top,
    /// Top right corner.
    TopRight,
    /// Left edge, centred.
    Left,
    /// The middle of the picture.
    Center,
    /// Right edge, centred.
    Right,
    /// Bottom left corner (above the scale bar, when there is one).
    BottomLeft,
    /// Bottom edge, centred.
    Bottom,
    /// Bottom right corner.
    BottomRight,
}

impl Position {
    /// Every position with its scene-file name.
    pub const ALL: &'static [(&'static str, Position)] = &[
        ("top-left", Position::TopLeft),
        ("top", Position::Top),
        ("top-right", Position::TopRight),
        ("left", Position::Left),
        ("center", Position::Center),
        ("right", Position::Right),
        ("bottom-left", Position::BottomLeft),
        ("bottom", Position::Bottom),
        ("bottom-right", Position::BottomRight),
    ];

    /// The scene-file name.
    pub fn name(self) -> &'static str {
        Position::ALL
            .iter()
            .find(|(_, p)| *p == self)
            .map_or("?", |(n, _)| n)
    }

    /// Column (0 left, 1 centre, 2 right) and row (0 top, 1 middle, 2 bottom).
    pub(crate) fn cell(self) -> (usize, usize) {
        let k = Position::ALL
            .iter()
            .position(|(_, p)| *p == self)
            .unwrap_or(0);
        (k % 3, k / 3)
    }
}

/// A piece of a label's text.
#[derive(Clone, Debug, PartialEq)]
pub enum Part {
    /// Written as it is.
    Text(String),
    /// `{scene}`: the scene file's name.
    Scene,
    /// `{pass}`: the pass's name.
    Pass,
    /// `{frame}`: the frame number.
    Frame,
    /// `{azimuth}`: the frame's azimuth in degrees, in [0, 360) (a stereo eye shows
    /// the frame's centre value).
    Azimuth,
    /// `{elevation}`: the camera's elevation in degrees.
    Elevation,
}

/// The placeholders of label text.
pub const PLACEHOLDERS: &[(&str, Part)] = &[
    ("scene", Part::Scene),
    ("pass", Part::Pass),
    ("frame", Part::Frame),
    ("azimuth", Part::Azimuth),
    ("elevation", Part::Elevation),
];

/// Splits label text into literal text and placeholders; `{{` and `}}` stand for
/// braces. The error names what is wrong.
pub fn parse_text(text: &str) -> Result<Vec<Part>, String> {
    let mut parts = Vec::new();
    let mut lit = String::new();
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '{' if chars.peek() == Some(&'{') => {
                chars.next();
                lit.push('{');
            }
            '}' if chars.peek() == Some(&'}') => {
                chars.next();
                lit.push('}');
            }
            '{' => {
                let name: String = chars.by_ref().take_while(|&c| c != '}').collect();
                let Some((_, p)) = PLACEHOLDERS.iter().find(|(n, _)| *n == name) else {
                    return Err(format!(
                        "`{{{name}}}` is not a placeholder: expected {} (write {{{{ and }}}} for braces)",
                        PLACEHOLDERS
                            .iter()
                            .map(|(n, _)| format!("{{{n}}}"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    ));
                };
                if !lit.is_empty() {
                    parts.push(Part::Text(std::mem::take(&mut lit)));
                }
                parts.push(p.clone());
            }
            '}' => return Err("a lone `}`: write }} for a brace".into()),
            c => lit.push(c),
        }
    }
    if !lit.is_empty() {
        parts.push(Part::Text(lit));
    }
    Ok(parts)
}

/// A `[[label]]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Label {
    /// The text, with placeholders.
    pub text: Vec<Part>,
    /// Where it sits.
    pub position: Position,
    /// Font size in pixels (the height of a line, ascent to descent).
    pub size: f32,
    /// Linear RGB in [0, 1].
    pub color: [f32; 3],
}

/// What the placeholders of a frame's labels stand for.
#[derive(Clone, Copy, Debug)]
pub struct FrameInfo<'a> {
    /// The scene file's name.
    pub scene: &'a str,
    /// The pass's name.
    pub pass: &'a str,
    /// The frame number.
    pub frame: usize,
    /// The frame's azimuth, degrees (any turn: shown in [0, 360)).
    pub azimuth: f64,
    /// The elevation, degrees.
    pub elevation: f64,
}

/// A number as labels show it: at most `decimals` decimals, no trailing zeros.
pub fn short_number(x: f64, decimals: usize) -> String {
    let s = format!("{x:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    if s == "-0" {
        "0".into()
    } else {
        s
    }
}

impl Label {
    /// The label's text for one frame.
    pub fn text_for(&self, f: &FrameInfo) -> String {
        self.text
            .iter()
            .map(|p| match p {
                Part::Text(t) => t.clone(),
                Part::Scene => f.scene.to_string(),
                Part::Pass => f.pass.to_string(),
                Part::Frame => f.frame.to_string(),
                Part::Azimuth => short_number(f.azimuth.rem_euclid(360.0), 2),
                Part::Elevation => short_number(f.elevation, 2),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placeholders_and_braces() {
        let parts = parse_text("{scene}: {{frame}} {frame} at {azimuth}°").unwrap();
        let label = Label {
            text: parts,
            position: Position::TopLeft,
            size: 12.0,
            color: [1.0; 3],
        };
        let info = FrameInfo {
            scene: "head",
            pass: "mip",
            frame: 7,
            azimuth: 390.5,
            elevation: -10.0,
        };
        assert_eq!(label.text_for(&info), "head: {frame} 7 at 30.5°");
        assert!(parse_text("{frmae}")
            .unwrap_err()
            .contains("`{frmae}` is not a placeholder"));
        assert!(parse_text("a } b").is_err());
    }

    #[test]
    fn numbers_are_short() {
        assert_eq!(short_number(120.0, 2), "120");
        assert_eq!(short_number(12.345, 2), "12.35");
        assert_eq!(short_number(-0.0001, 2), "0");
    }
}

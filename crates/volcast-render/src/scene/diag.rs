//! Scene errors that point into the file: `path:line:column`, the offending line
//! with a caret under the value, what was expected and, for misspelt names, the
//! closest valid one.

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// One problem in a scene file.
#[derive(Clone, Debug, PartialEq)]
pub struct Diagnostic {
    /// Byte range in the file, when the problem has a place.
    pub span: Option<Range<usize>>,
    /// What is wrong and what was expected.
    pub message: String,
}

/// Everything wrong with a scene file (all problems found, not just the first).
#[derive(Clone, Debug, PartialEq)]
pub struct SceneError {
    /// The scene file.
    pub path: PathBuf,
    /// Its text (for line/column and the quoted line).
    pub text: String,
    /// The problems, in file order.
    pub diagnostics: Vec<Diagnostic>,
}

impl std::error::Error for SceneError {}

impl SceneError {
    /// A single problem without a place in the file (e.g. the file cannot be read).
    pub fn whole_file(path: &Path, message: impl Into<String>) -> SceneError {
        SceneError {
            path: path.to_path_buf(),
            text: String::new(),
            diagnostics: vec![Diagnostic {
                span: None,
                message: message.into(),
            }],
        }
    }

    /// 1-based line and column of a byte offset.
    pub fn line_col(&self, offset: usize) -> (usize, usize) {
        line_col(&self.text, offset)
    }
}

/// 1-based line and column (in characters) of byte `offset` in `text`.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text[..floor_char_boundary(text, offset)];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

fn floor_char_boundary(s: &str, mut i: usize) -> usize {
    i = i.min(s.len());
    while i > 0 && !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.diagnostics.len();
        for (idx, d) in self.diagnostics.iter().enumerate() {
            if idx > 0 {
                writeln!(f)?;
            }
            match &d.span {
                Some(span) if !self.text.is_empty() => {
                    let (line, col) = self.line_col(span.start);
                    writeln!(f, "{}:{line}:{col}: {}", self.path.display(), d.message)?;
                    let src = self.text.lines().nth(line - 1).unwrap_or("");
                    let width = line.to_string().len();
                    let start = floor_char_boundary(&self.text, span.start);
                    let end = floor_char_boundary(&self.text, span.end).max(start);
                    let span_text = &self.text[start..end];
                    let first_line_len = span_text
                        .split('\n')
                        .next()
                        .map_or(0, |s| s.chars().count());
                    let carets =
                        first_line_len.clamp(1, src.chars().count().saturating_sub(col - 1).max(1));
                    writeln!(f, "{:width$} |", "")?;
                    writeln!(f, "{line} | {src}")?;
                    write!(
                        f,
                        "{:width$} | {}{}",
                        "",
                        " ".repeat(col - 1),
                        "^".repeat(carets)
                    )?;
                }
                _ => write!(f, "{}: {}", self.path.display(), d.message)?,
            }
        }
        if n > 1 {
            write!(f, "\n({n} problems in this scene)")?;
        }
        Ok(())
    }
}

/// The candidate closest to `word` by edit distance, if it is close enough to be a
/// plausible typo (distance at most a third of the word's length, and at least 1).
pub fn suggest<'a>(word: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let word_l = word.to_ascii_lowercase();
    let max = (word.chars().count() / 3).max(1);
    candidates
        .into_iter()
        .map(|c| (edit_distance(&word_l, &c.to_ascii_lowercase()), c))
        .filter(|&(d, _)| d <= max)
        .min_by_key(|&(d, _)| d)
        .map(|(_, c)| c)
}

/// Levenshtein distance, with an adjacent transposition counting as one edit.
fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let mut prev2 = vec![0usize; b.len() + 1];
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    let mut cur = vec![0usize; b.len() + 1];
    for i in 1..=a.len() {
        cur[0] = i;
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            cur[j] = (prev[j] + 1).min(cur[j - 1] + 1).min(prev[j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                cur[j] = cur[j].min(prev2[j - 2] + 1);
            }
        }
        std::mem::swap(&mut prev2, &mut prev);
        std::mem::swap(&mut prev, &mut cur);
    }
    prev[b.len()]
}

/// Formats `["a", "b"]` as "`a`, `b`".
pub fn quoted_list<'a>(items: impl IntoIterator<Item = &'a str>) -> String {
    items
        .into_iter()
        .map(|s| format!("`{s}`"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Improves a serde/toml message: for an unknown key or value, appends the closest
/// of the expected names ("did you mean `iso`?").
pub fn with_suggestion(message: &str) -> String {
    // serde's forms: "unknown field `x`, expected one of `a`, `b`" / "expected `a` or `b`"
    //                "unknown variant `x`, expected one of ..."
    let Some(rest) = message
        .strip_prefix("unknown field `")
        .or_else(|| message.strip_prefix("unknown variant `"))
    else {
        return message.to_string();
    };
    let Some((word, expected)) = rest.split_once('`') else {
        return message.to_string();
    };
    let names: Vec<&str> = expected.split('`').skip(1).step_by(2).collect();
    match suggest(word, names.iter().copied()) {
        Some(s) => format!("{message}; did you mean `{s}`?"),
        None => message.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suggestions() {
        assert_eq!(suggest("isoo", ["iso", "mode", "step"]), Some("iso"));
        assert_eq!(
            suggest("trilienar", ["nearest", "trilinear", "cubic"]),
            Some("trilinear")
        );
        assert_eq!(suggest("zzzzzz", ["iso", "mode"]), None);
        assert_eq!(
            with_suggestion("unknown field `isoo`, expected one of `name`, `iso`"),
            "unknown field `isoo`, expected one of `name`, `iso`; did you mean `iso`?"
        );
    }

    #[test]
    fn positions() {
        let t = "a = 1\nbé = 2\n";
        assert_eq!(line_col(t, 0), (1, 1));
        assert_eq!(line_col(t, 6), (2, 1));
        assert_eq!(line_col(t, t.find('=').unwrap()), (1, 3));
        let e = SceneError {
            path: "s.toml".into(),
            text: t.into(),
            diagnostics: vec![Diagnostic {
                span: Some(12..13),
                message: "bad".into(),
            }],
        };
        let shown = e.to_string();
        assert!(shown.starts_with("s.toml:2:6: bad"), "{shown}");
        assert!(shown.contains("2 | bé = 2"), "{shown}");
        // spans inside a character or past the end never panic
        #[allow(clippy::reversed_empty_ranges)]
        let spans = [7..8, 8..7, 0..1000, 1000..2000];
        for span in spans {
            let e = SceneError {
                diagnostics: vec![Diagnostic {
                    span: Some(span),
                    message: "x".into(),
                }],
                ..e.clone()
            };
            assert!(e.to_string().contains("s.toml:"));
        }
    }
}

//! Errors that point into an input file: `path:line:column: message`, plus a rustc-style
//! excerpt of the offending source for people.

use std::fmt;
use std::ops::Range;

/// A problem at a place in a text file.
///
/// `Display` gives the one-line form `scene.toml:4:16: major_radius must be positive ...`
/// that scripts can parse; [`Diagnostic::render`] adds the source line with a caret under the
/// offending value, as rustc and cargo print it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Diagnostic {
    /// The file's name as given (or `<stdin>`).
    pub path: String,
    /// 1-based line of the problem's start.
    pub line: usize,
    /// 1-based column (in characters) of the problem's start.
    pub column: usize,
    /// What is wrong.
    pub message: String,
    /// The source lines holding the problem (at most a few), for [`Diagnostic::render`].
    excerpt: String,
    /// The problem's byte range within `excerpt`.
    excerpt_span: Range<usize>,
}

/// Most source lines quoted in an excerpt.
const MAX_EXCERPT_LINES: usize = 4;
/// Longest quoted excerpt, in bytes; longer lines are quoted only up to here.
const MAX_EXCERPT_BYTES: usize = 400;
/// Longest message, in characters: one that quotes a huge value is cut.
const MAX_MESSAGE_CHARS: usize = 200;

impl Diagnostic {
    /// A diagnostic for the bytes `span` of `source` (clamped to the source; an empty span
    /// points at one place).
    pub fn new(path: &str, source: &str, span: Range<usize>, message: impl Into<String>) -> Self {
        let start = floor_char_boundary(source, span.start.min(source.len()));
        let end = floor_char_boundary(source, span.end.clamp(start, source.len()));
        let line_start = source[..start].rfind('\n').map_or(0, |i| i + 1);
        let line = source[..start].bytes().filter(|&b| b == b'\n').count() + 1;
        let column = source[line_start..start].chars().count() + 1;
        // Quote whole lines from the problem's line, at most a few of them.
        let mut excerpt_end = line_start;
        for _ in 0..MAX_EXCERPT_LINES {
            match source[excerpt_end..].find('\n') {
                Some(i) => excerpt_end += i + 1,
                None => {
                    excerpt_end = source.len();
                    break;
                }
            }
            if excerpt_end > end {
                break;
            }
        }
        // Far into a long line, quote from a little before the problem.
        let begin = if start - line_start > MAX_EXCERPT_BYTES / 2 {
            floor_char_boundary(source, start - MAX_EXCERPT_BYTES / 4)
        } else {
            line_start
        };
        let excerpt_end = floor_char_boundary(
            source,
            excerpt_end.min(begin + MAX_EXCERPT_BYTES).max(start),
        );
        let excerpt = source[begin..excerpt_end]
            .trim_end_matches(['\n', '\r'])
            .to_string();
        let rel_start = (start - begin).min(excerpt.len());
        let rel_end = (end - begin).clamp(rel_start, excerpt.len());
        Diagnostic {
            path: path.to_string(),
            line,
            column,
            message: crate::limits::cut(&message.into(), MAX_MESSAGE_CHARS),
            excerpt,
            excerpt_span: rel_start..rel_end,
        }
    }

    /// The rustc-style report: the one-line form, then the source line with a caret.
    pub fn render(&self) -> String {
        use annotate_snippets::{AnnotationKind, Group, Level, Renderer, Snippet};
        let title = self.to_string();
        let mut span = self.excerpt_span.clone();
        if span.is_empty() {
            // Point at one character rather than between two.
            span.end += self.excerpt[span.start..]
                .chars()
                .next()
                .map_or(0, char::len_utf8);
        }
        let report = [
            Group::with_title(Level::ERROR.primary_title(title)).element(
                Snippet::source(self.excerpt.as_str())
                    .line_start(self.line)
                    .path(self.path.as_str())
                    .fold(false)
                    .annotation(AnnotationKind::Primary.span(span)),
            ),
        ];
        Renderer::plain().render(&report)
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:{}: {}",
            self.path, self.line, self.column, self.message
        )
    }
}

impl std::error::Error for Diagnostic {}

/// The largest char boundary of `s` at or below `i`.
fn floor_char_boundary(s: &str, mut i: usize) -> usize {
    i = i.min(s.len());
    while !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locates_line_and_column_in_characters() {
        let src = "a = 1\n# é\nmajor_radius = [0.0, 0.03]\n";
        let at = src.find("[0.0").unwrap();
        let d = Diagnostic::new(
            "scene.toml",
            src,
            at..at + 11,
            "major_radius must be positive",
        );
        assert_eq!(
            d.to_string(),
            "scene.toml:3:16: major_radius must be positive",
            "{d:?}"
        );
        let r = d.render();
        assert!(r.contains("scene.toml:3:16"), "{r}");
        assert!(r.contains("major_radius = [0.0, 0.03]"), "{r}");
        assert!(r.contains("^^^^^^^^^^^"), "{r}");
    }

    #[test]
    fn huge_lines_and_messages_are_cut() {
        let value = "x".repeat(10_000_000);
        let src = format!("a = 1\nname = \"{value}\" oops\n");
        let at = src.find(" oops").unwrap();
        let d = Diagnostic::new("s.toml", &src, at..at + 5, format!("bad value {value}"));
        assert!(d.message.len() < 500, "{}", d.message.len());
        let r = d.render();
        assert!(r.len() < 2000, "{}", r.len());
        assert!(r.contains("oops"), "{r}");
        assert_eq!(d.line, 2);
        assert_eq!(d.column, at - 6 + 1);
    }

    #[test]
    fn survives_odd_spans() {
        let src = "é\né";
        #[allow(clippy::reversed_empty_ranges)]
        for span in [0..0, 1..1, 0..100, 3..2, 50..60, 2..3, 4..5] {
            let d = Diagnostic::new("f", src, span.clone(), "m");
            let _ = d.render();
            assert!(d.line >= 1 && d.column >= 1, "{span:?} gave {d:?}");
        }
        let d = Diagnostic::new("f", "", 0..0, "empty");
        assert_eq!(d.to_string(), "f:1:1: empty", "empty source");
        let _ = d.render();
    }
}
